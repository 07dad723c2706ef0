"""What runs is what the FMU holds: a Python FMU runs only the code in its own resources/.

The trap these tests catch (0.3): an FMU's bundled packages were imported under their
own top-level names into the process's one ``sys.modules``, so the first copy loaded
won. A controller whose ``laws.py`` divides the passivity law by ``K_c * 1.01`` instead
of ``K_c`` then passed ``verify`` 7 of 7 and gave the default run's ``results.csv`` in
any process that had imported ``glider_controller`` (or another copy of the FMU) first.

Each test runs the original and the modified controller, FMI 2 and FMI 3, in one host
that imported our packages first: fmpy, our master (through a scenario), the kit, a Dask
worker, libcosim. The modification scales every unsaturated passivity command by
exactly 1 / 1.01, which the tests check where the inputs are the same.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest

from glider_cosim.cli import main
from glider_cosim.runner import simulate
from glider_cosim.runner.provenance import file_sha256
from glider_cosim.scenarios.scenario import parse_scenario
from glider_cosim.testing import assert_matches_reference
from glider_cosim.verify import verify

pytestmark = pytest.mark.integration

LAWS = "resources/glider_controller/laws.py"
ORIGINAL_LINE = "/ K_c\n"
MODIFIED_LINE = "/ (K_c * 1.01)\n"
#: controller inputs off the equilibrium (the passivity command is about -0.06 rad there)
INPUTS = {"V_hat": 0.25, "theta_g_hat": -0.36}


def modify_controller(src: Path, dst: Path) -> Path:
    """A copy of ``src`` whose passivity law divides by ``K_c * 1.01`` (one line changed)."""
    with zipfile.ZipFile(src) as z, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as out:
        for item in z.infolist():
            data = z.read(item)
            if item.filename == LAWS:
                text = data.decode()
                assert text.count(ORIGINAL_LINE) == 1, "the passivity law's line moved"
                data = text.replace(ORIGINAL_LINE, MODIFIED_LINE).encode()
            out.writestr(item, data)
    return dst


@pytest.fixture(scope="module", params=["fmi2", "fmi3"])
def pair(request, fmu_dir, fmi3_dirs, tmp_path_factory) -> tuple[Path, Path]:
    """(original, modified) Python-flavor controller, FMI 2 and FMI 3."""
    folder = fmu_dir if request.param == "fmi2" else fmi3_dirs["python"]
    original = folder / "GliderController.fmu"
    out = tmp_path_factory.mktemp(f"modified_{request.param}")
    return original, modify_controller(original, out / "MyController.fmu")


def test_the_modified_controller_fails_verify_on_the_law_cases(pair, capsys):
    import glider_controller  # noqa: F401  the host's own copy, imported first

    original, modified = pair
    assert main(["verify", str(original), "--kit"]) == 0
    capsys.readouterr()
    assert main(["verify", str(modified), "--kit"]) == 1
    out = capsys.readouterr().out
    cases = ("passivity", "anti_windup", "enable_time", "open_loop", "p", "pi", "saturation")
    rows = {line.split()[0]: line.split()[1] for line in out.splitlines()
            if line.split()[:1] and line.split()[0] in cases}  # fmt: skip
    # a port of our law: the loop's checks pass, the law's reference cases count
    assert "closed loop     pass" in out and "a port of our laws, held to them" in out
    # the passivity law runs in these two; the others use P, PI or open loop
    assert rows.pop("passivity") == "FAIL" and rows.pop("enable_time") == "FAIL", out
    assert set(rows.values()) == {"pass"}, out
    assert "5 of 7 cases pass" in out
    report = verify(modified, "controller", "passivity")
    worst = report.results[0]
    assert worst.value == pytest.approx(worst.ref_value / 1.01, rel=1e-12, abs=0)
    with pytest.raises(AssertionError, match=r"2 of 7 controller cases fail:\n.*'passivity' fails"):
        assert_matches_reference(modified, "controller")
    assert_matches_reference(original, "controller")  # and the original still passes after


FMPY_ONE_PROCESS = """
import json, sys, tempfile, zipfile
from pathlib import Path
original, modified, host_first = sys.argv[1:4]
if host_first == "shadow":  # a modified glider_controller first on sys.path, the host's own
    import shutil, glider_controller as installed
    tmp = Path(tempfile.mkdtemp()) / "glider_controller"
    shutil.copytree(Path(installed.__file__).parent, tmp)
    laws = tmp / "laws.py"
    laws.write_text(laws.read_text().replace(ORIGINAL, MODIFIED))
    del sys.modules["glider_controller"]
    sys.path.insert(0, str(tmp.parent))
import glider_cosim, glider_cosim.verify, glider_controller, glider_controller.laws, pythonfmu
from fmpy import simulate_fmu
host = (glider_controller.__file__, glider_controller.laws.passivity_law)
path = list(sys.path)

def run(fmu):
    r = simulate_fmu(fmu, start_values=INPUTS, stop_time=0.1, output_interval=0.02,
                     output=["delta_cmd"])
    return float(r["delta_cmd"][-1])

values = [run(original), run(modified), run(original), run(modified)]
same_host = (glider_controller.__file__, glider_controller.laws.passivity_law) == host
print(json.dumps({"values": values, "same_host": same_host and sys.modules["glider_controller"]
                  is glider_controller, "sys_path_kept": sys.path == path,
                  "host_file": glider_controller.__file__}))
"""


@pytest.mark.parametrize("host_first", ["packages", "shadow"])
def test_fmpy_runs_each_fmu_own_code_in_one_process(pair, host_first, tmp_path):
    """Our packages imported first (or, "shadow", the host's own modified copy of
    glider_controller first on sys.path): each FMU runs its own code, in any order, and
    the host's modules and sys.path are left as they were."""
    original, modified = pair
    script = FMPY_ONE_PROCESS.replace("INPUTS", repr(INPUTS))
    for key, line in (("ORIGINAL", ORIGINAL_LINE), ("MODIFIED", MODIFIED_LINE)):
        script = script.replace(key, repr(line))
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    p = subprocess.run([sys.executable, "-c", script, str(original), str(modified), host_first],
                       capture_output=True, text=True, timeout=300, env=env)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    got = json.loads(p.stdout.strip().splitlines()[-1])
    a, b, a2, b2 = got["values"]
    assert abs(a) > 0.01  # the inputs give an unsaturated, non-zero command
    assert b == pytest.approx(a / 1.01, rel=1e-12, abs=0)  # the change, as predicted
    assert (a2, b2) == (a, b)  # bit for bit on the second run of each
    assert got["same_host"] and got["sys_path_kept"], got
    assert got["host_file"].startswith(str(tmp_path)) == (host_first == "shadow")


def test_a_master_run_with_the_modified_controller_differs(pair, fmu_dir, tmp_path):
    original, modified = pair
    runs = {}
    for name, fmu in (("original", original), ("modified", modified)):
        sc = parse_scenario({"name": name, "stop_time": 10.0, "fmus": {"controller": str(fmu)}})
        runs[name] = simulate(sc, tmp_path / name, fmu_dir=fmu_dir, build=False, plots=False)
    default = simulate(parse_scenario({"stop_time": 10.0}), None, fmu_dir=fmu_dir, build=False)
    a, b = (runs[k].column("controller.delta_cmd") for k in ("original", "modified"))
    # the original (FMI 2, or FMI 3 which equals it bit for bit) is the default run's
    assert np.array_equal(a, default.column("controller.delta_cmd"))
    diff = np.abs(a - b)
    assert diff.max() > 1e-3, diff.max()
    k = int(np.flatnonzero(a)[0])  # first non-zero command: both loops equal up to it
    assert b[k] == pytest.approx(a[k] / 1.01, rel=1e-12, abs=0)
    shas = {k: json.loads((tmp_path / k / "metrics.json").read_text())["run"]["fmus"]
            ["controller"]["sha256"] for k in runs}  # fmt: skip
    assert shas == {k: file_sha256(f) for k, f in (("original", original), ("modified", modified))}
    assert (tmp_path / "modified" / "results.csv").read_bytes() != (
        tmp_path / "original" / "results.csv"
    ).read_bytes()


def test_a_dask_worker_runs_the_modified_controller_after_the_original(pair):
    """On the sweeps' own local cluster (one worker process, no dashboard)."""
    from glider_cosim.sweeps.cluster import make_client

    original, modified = pair
    client = make_client(1)
    try:
        pid1 = client.submit(os.getpid, pure=False).result()
        first = client.submit(verify, original, "controller", pure=False).result()
        second = client.submit(verify, modified, "controller", pure=False).result()
        third = client.submit(verify, original, "controller", pure=False).result()
        assert client.submit(os.getpid, pure=False).result() == pid1  # one worker process
    finally:
        client.close()
        client.cluster.close()
    assert first.passed and third.passed
    assert not second.passed
    failed = sorted(r.case.name for r in second.results if not r.passed)
    assert failed == ["enable_time", "passivity"]


LIBCOSIM_SCRIPT = """
import json, sys
import glider_cosim, glider_controller, glider_controller.laws, glider_plant, pythonfmu
from glider_cosim.interop.libcosim import simulate_libcosim
r = simulate_libcosim(sys.argv[1], ["controller.delta_cmd"], stop_time=5.0)
print(json.dumps(r.column("controller.delta_cmd").tolist()))
"""


def test_libcosim_in_a_process_with_our_packages_runs_the_fmu_own_code(fmu_dir, tmp_path):
    from glider_cosim.interop.ssp_export import export_ssp

    original = fmu_dir / "GliderController.fmu"
    modified = modify_controller(original, tmp_path / "MyController.fmu")
    columns = {}
    ours = {}
    for name, fmu in (("original", original), ("modified", modified)):
        sc = parse_scenario({"name": name, "stop_time": 5.0, "coupling": "jacobi",
                             "fmus": {"controller": str(fmu)}})  # fmt: skip
        ssp = export_ssp(tmp_path / f"{name}.ssp", sc, fmu_dir)
        p = subprocess.run([sys.executable, "-c", LIBCOSIM_SCRIPT, str(ssp)], capture_output=True,
                           text=True, timeout=300)  # fmt: skip
        assert p.returncode == 0, p.stderr[-2000:]
        columns[name] = np.array(json.loads(p.stdout.strip().splitlines()[-1]))
        ours[name] = simulate(sc, None, fmu_dir=fmu_dir, build=False).column("controller.delta_cmd")
    a, b = columns["original"], columns["modified"]
    assert np.abs(a - b).max() > 1e-3
    for name in columns:  # libcosim ran what our master ran (Jacobi), each its own code
        n = min(len(columns[name]), len(ours[name]))
        assert np.abs(columns[name][:n] - ours[name][:n]).max() < 1e-12, name


def test_two_builds_of_one_component_share_nothing_but_identical_code(fmu_dir, tmp_path):
    """The same FMU unpacked twice shares one package (the same code), a changed one gets
    its own; the packages are named after the code's SHA-256 and put nothing on sys.path."""
    original = fmu_dir / "GliderController.fmu"
    modified = modify_controller(original, tmp_path / "MyController.fmu")
    script = textwrap.dedent(f"""
        import sys
        from fmpy import simulate_fmu
        path = list(sys.path)
        for f in ({str(original)!r}, {str(original)!r}, {str(modified)!r}):
            simulate_fmu(f, stop_time=0.04, output_interval=0.02)
        roots = sorted(m for m in sys.modules if m.startswith("_glider_fmu_") and "." not in m)
        print(len(roots), sys.path == path, "glider_controller" in sys.modules,
              all(len(m) == len("_glider_fmu_") + 32 for m in roots))
    """)
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    assert p.stdout.split() == ["2", "True", "False", "True"]


def test_the_bundled_code_imports_only_relatively(fmu_dir):
    """Every import of a bundled name inside an FMU is relative (the build's rewrite)."""
    import ast

    from glider_fmi.bundle import bundle_names

    with zipfile.ZipFile(fmu_dir / "GliderController.fmu") as z:
        files = {n.removeprefix("resources/"): z.read(n) for n in z.namelist()
                 if n.startswith("resources/") and n.endswith(".py")}  # fmt: skip
    names = bundle_names(files)
    assert {"glider_controller", "glider_plant", "glider_fmi", "pythonfmu"} <= names
    absolute = []
    for path, data in files.items():
        for node in ast.walk(ast.parse(data)):
            if isinstance(node, ast.ImportFrom) and node.level == 0:
                if node.module.partition(".")[0] in names:
                    absolute.append(f"{path}: from {node.module}")
            elif isinstance(node, ast.Import):
                absolute += [f"{path}: import {a.name}" for a in node.names
                             if a.name.partition(".")[0] in names]  # fmt: skip
    assert absolute == []
    slave = files["glider_controller/slave.py"].decode()
    assert "from ..glider_controller.laws import" in slave
