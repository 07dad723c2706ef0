"""The recipes of docs/how-to/use-the-fmus.md run as written (issue 45 item 4).

Each test takes its code block from the page as it stands, runs it in a folder laid out as
the page says (``fmus/`` from ``glider-cosim build``, ``fmus/native/`` for the native
flavor) and compares what it wrote with our master:

- the fmpy loop with ``glider-cosim run``'s ``results.csv``, bit for bit on every value of
  every row (Gauss-Seidel, the default), on both flavors;
- the C host with ``run --coupling jacobi``, bit for bit;
- Ecos with ``run glider.ssp --coupling jacobi``, on both flavors;
- fmusim (where it is on ``PATH``: it is on no package registry) with the verification
  kit's plant ``release`` reference.

The libcosim recipe has its own test, test_libcosim_recipe.py.
"""

from __future__ import annotations

import csv
import os
import re
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from system_tools import require_tool

from glider_cosim.interop.ssp_export import export_ssp
from glider_cosim.runner import run_ssp, simulate
from glider_cosim.verify import kit_root

pytestmark = pytest.mark.integration
ROOT = Path(__file__).parents[2]
PAGE = ROOT / "docs" / "how-to" / "use-the-fmus.md"


def block(language: str, marker: str) -> str:
    """The one code block of ``language`` on the page that contains ``marker``."""
    blocks = re.findall(rf"^```{language}\n(.*?)^```", PAGE.read_text(), re.M | re.S)
    found = [b for b in blocks if marker in b]
    assert len(found) == 1, f"expected one {language} block with {marker!r} in {PAGE.name}"
    return found[0]


def env() -> dict[str, str]:
    """This environment with this interpreter's folder first on PATH (``python`` and
    ``glider-cosim`` of the venv under test)."""
    return {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}


def run(argv: list[str], cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    p = subprocess.run(argv, cwd=cwd, env=env(), capture_output=True, text=True,
                       timeout=timeout)  # fmt: skip
    assert p.returncode == 0, f"{argv}: {p.stderr[-3000:]}"
    return p


def bits(row: list[str]) -> list[bytes]:
    return [struct.pack("<d", float(x)) for x in row]


def assert_rows_equal(ours: Path, theirs: Path) -> None:
    """Same header, same rows, every value the same float64 (bit for bit)."""
    a = list(csv.reader(ours.open()))
    b = list(csv.reader(theirs.open()))
    assert a[0] == b[0], "columns differ"
    assert len(a) == len(b), f"{len(a) - 1} rows against {len(b) - 1}"
    for k, (x, y) in enumerate(zip(a[1:], b[1:])):
        if bits(x) != bits(y):
            col = next(j for j, (u, v) in enumerate(zip(bits(x), bits(y))) if u != v)
            pytest.fail(f"row {k} (t = {y[0]}) differs first in {a[0][col]}: {x[col]} "
                        f"against run's {y[col]}")  # fmt: skip


def fmus_folder(flavor: str, where: Path, request) -> Path:
    """``where/fmus`` as the page has it: built by ``glider-cosim build`` (Python flavor),
    or the session's native build linked there (as ``glider-cosim build --flavor
    native`` makes it; a cold native build takes minutes). Returns the FMU folder."""
    if flavor == "python":
        run(["glider-cosim", "build", "--out", "fmus"], where)
        return where / "fmus"
    native = request.getfixturevalue("native_dir")
    (where / "fmus").symlink_to(native, target_is_directory=True)
    return native


@pytest.mark.parametrize("flavor", ["python", "native"])
def test_the_fmpy_loop_equals_run_bit_for_bit(flavor, request, tmp_path):
    code = block("python", "FMU2Slave")
    assert 35 <= len([line for line in code.splitlines() if line.strip()]) <= 50
    folder = fmus_folder(flavor, tmp_path, request)
    (tmp_path / "recipe.py").write_text(code)
    p = run([sys.executable, "recipe.py"], tmp_path)
    assert p.stdout == "" and p.stderr == ""
    run(["glider-cosim", "run", "--fmu-dir", str(folder), "--out", "out", "--no-plots"],
        tmp_path)  # fmt: skip
    ours = tmp_path / "fmpy-results.csv"
    assert_rows_equal(ours, tmp_path / "out" / "results.csv")
    assert len(ours.read_text().splitlines()) == 3002  # 60 s at 50 Hz and the header
    if flavor == "python":  # another K_c, as the page says: the run of `run --set`
        other = code.replace('{"K_c": 10.0}', '{"K_c": 6.0}')
        assert other != code
        (tmp_path / "recipe.py").write_text(other)
        run([sys.executable, "recipe.py"], tmp_path)
        run(["glider-cosim", "run", "--fmu-dir", str(folder), "--out", "out6", "--no-plots",
             "--set", "controller.K_c=6"], tmp_path)  # fmt: skip
        assert_rows_equal(ours, tmp_path / "out6" / "results.csv")


def test_the_fmpy_loop_check_sees_one_changed_bit(tmp_path):
    """The comparison above can fail: one value off by one ulp is found."""
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_text("time,x\n0.0,0.1\n0.02,0.2\n")
    b.write_text(f"time,x\n0.0,0.1\n0.02,{float(np.nextafter(0.2, 1.0))!r}\n")
    with pytest.raises(pytest.fail.Exception, match=r"row 1 \(t = 0.02\) differs first in x"):
        assert_rows_equal(a, b)


def test_the_c_host_equals_run_jacobi_bit_for_bit(native_dir, tmp_path):
    require_tool("gcc")
    (tmp_path / "fmus").mkdir()
    (tmp_path / "fmus" / "native").symlink_to(native_dir, target_is_directory=True)
    (tmp_path / "tests" / "integration").mkdir(parents=True)  # as in a clone
    (tmp_path / "tests" / "integration" / "c_host").symlink_to(
        ROOT / "tests" / "integration" / "c_host", target_is_directory=True
    )
    (tmp_path / "recipe.sh").write_text(block("sh", "c_host/host.c"))
    run(["bash", "-e", "recipe.sh"], tmp_path)
    c_rows = np.loadtxt(tmp_path / "c-host" / "results.csv", delimiter=",")
    ours = simulate(None, None, fmu_dir=native_dir, build=False, coupling="jacobi", plots=False)
    cols = ["time", "plant.theta_g", "controller.delta_cmd"]
    expected = np.column_stack([ours.column(c) for c in cols])
    assert c_rows.shape == expected.shape == (3001, 3)
    assert np.array_equal(c_rows, expected)  # bit for bit (%.17g round-trips)


@pytest.mark.parametrize("flavor", ["python", "native"])
def test_the_ecos_recipe_prints_run_jacobis_value(flavor, request, tmp_path):
    folder = request.getfixturevalue("fmu_dir" if flavor == "python" else "native_dir")
    ssp = export_ssp(tmp_path / "glider.ssp", None, folder)
    (tmp_path / "recipe.py").write_text(block("python", "EcosSimulation"))
    scratch = tmp_path / "ecos_tmp"  # Ecos leaves its unpacked SSP in $TMPDIR
    scratch.mkdir()
    p = subprocess.run([sys.executable, "recipe.py"], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300, env={**env(), "TMPDIR": str(scratch)})  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    theta_g = run_ssp(ssp, None, coupling="jacobi", stop_time=20.0).column("plant.theta_g")[-1]
    assert p.stdout == f"theta_g(20 s) = {theta_g:.6f} rad\n"
    assert "theta_g(20 s) = -0.395346 rad" in PAGE.read_text()  # the value the page shows
    assert f"{theta_g:.6f}" == "-0.395346"


@pytest.mark.parametrize("flavor", ["python", "native"])
def test_fmusim_runs_the_plant_as_the_kits_release_case(flavor, request, tmp_path):
    fmusim = shutil.which("fmusim")
    if fmusim is None:
        pytest.skip("fmusim is not on PATH (it is on no package registry: build it from the "
                    "Reference FMUs' sources)")  # fmt: skip
    folder = request.getfixturevalue("fmu_dir" if flavor == "python" else "native_dir")
    (tmp_path / "fmus").symlink_to(folder, target_is_directory=True)
    (tmp_path / "recipe.sh").write_text(block("sh", "fmusim --interface-type"))
    run(["bash", "-e", "recipe.sh"], tmp_path)
    got = np.genfromtxt(tmp_path / "plant.csv", delimiter=",", names=True)
    ref = np.genfromtxt(kit_root() / "plant" / "release_ref.csv", delimiter=",", names=True)
    assert got.dtype.names == ref.dtype.names and len(got) == len(ref) == 501
    for name in ref.dtype.names:  # the page's figure: within 2.5e-15
        assert np.abs(got[name] - ref[name]).max() <= 2.5e-15, name
