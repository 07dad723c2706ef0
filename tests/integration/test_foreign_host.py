"""A "foreign" machine: our C host runs the FMUs where only Debian's python3 is left.

The C host of test_c_host.py runs inside ``unshare -m`` (a mount namespace of its own)
under ``env -i``, with a tmpfs mounted over the build virtual environment, the building
interpreter's installation (``sys.prefix``, ``sys.base_prefix`` and the pyenv root above
them), this repository (the sources the FMUs were built from) and any site-packages
folder holding numpy. Before the result counts, the namespace is checked: the recorded
libpython does not exist there and ``/usr/bin/python3 -c 'import numpy'`` fails. The
FMUs' runtime must then find Debian's Python itself (python3 on PATH) and import only the
standard library and what the FMUs bundle. The results must equal the same host's on the
building machine (each FMU alone) and our master's Jacobi run (the closed loop) bit for
bit.

Needs root (or user namespaces) for ``unshare -m`` and Debian's ``python3`` with its
shared library (``.ci/run`` installs ``python3 libpython3.11``); otherwise the tests are
skipped with the reason.
"""

# ruff: noqa: F811 (the fixtures host and loop come from test_c_host)
from __future__ import annotations

import glob
import os
import shlex
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from system_tools import require_tool, tool_missing
from test_c_host import EMPTY_ENV, STOP, host, loop, master_jacobi  # noqa: F401

from glider_fmi.compile import libpython

pytestmark = pytest.mark.integration
ROOT = Path(__file__).resolve().parents[2]
DEBIAN_PYTHON = Path("/usr/bin/python3")
#: each FMU alone: inputs held (as bench/fmu_step.py), outputs recorded
ALONE = {
    "GliderPlant": ({"delta_cmd": 0.034906585039886591}, ["theta_g", "V", "delta", "theta_meas"]),
    "GliderObserver": ({"theta_meas": -0.4, "delta_cmd": 0.0}, ["V_hat", "theta_g_hat"]),
    "GliderController": ({"V_hat": 0.22, "theta_g_hat": -0.45}, ["delta_cmd"]),
}


def _numpy_site(python: str) -> str | None:
    """The site folder ``python`` imports numpy from, if it has one."""
    code = "import numpy, os; print(os.path.dirname(os.path.dirname(numpy.__file__)))"
    p = subprocess.run([python, "-c", code], capture_output=True, text=True, timeout=60)
    return p.stdout.strip() or None if p.returncode == 0 else None


def hidden_folders() -> list[str]:
    """What the namespace hides: deepest-first would not work (a tmpfs over a parent
    hides the child's mount point), so folders under another hidden one are dropped."""
    folders = {sys.prefix, sys.base_prefix, str(ROOT)}
    for prefix in (sys.prefix, sys.base_prefix):
        parts = Path(prefix).parts
        if "versions" in parts:  # pyenv: <root>/versions/<version>
            folders.add(str(Path(*parts[: parts.index("versions")])))
    for python in (sys.executable, str(DEBIAN_PYTHON)):
        site = _numpy_site(python)
        if site:
            folders.add(site)
    real = sorted({os.path.realpath(f) for f in folders if Path(f).is_dir()})
    return [f for f in real if not any(f != g and f.startswith(g + "/") for g in real)]


@pytest.fixture(scope="module")
def foreign():
    """A function running a command in the foreign namespace (skips with the reason)."""
    unshare = require_tool("unshare", install="apt-get install util-linux")
    p = subprocess.run([unshare, "-m", "true"], capture_output=True, text=True, timeout=30)
    if p.returncode != 0:
        pytest.skip(f"unshare -m is not permitted here: {p.stderr.strip()}")
    if not DEBIAN_PYTHON.is_file() or not glob.glob("/usr/lib/*/libpython3.1[1-9].so.1.0"):
        tool_missing("Debian's python3 and libpython3.11 are not installed "
                     "(apt-get install python3 libpython3.11; .ci/run installs them)")  # fmt: skip
    folders = hidden_folders()
    mounts = " && ".join(f"mount -t tmpfs tmpfs {shlex.quote(f)}" for f in folders)
    checks = (
        f"test ! -e {shlex.quote(str(libpython()))} && "
        f"test ! -e {shlex.quote(sys.executable)} && "
        f"! {DEBIAN_PYTHON} -c 'import numpy' 2>/dev/null && "
        f"! {DEBIAN_PYTHON} -c 'import pythonfmu' 2>/dev/null"
    )

    def run(argv: list[str], env: dict[str, str], extra: str = "true"):
        script = (
            f"mount --make-rprivate / && {mounts} && {extra} && "
            f"if ! {{ {checks}; }}; then echo 'FOREIGN: the build Python is still visible' >&2; "
            "exit 99; fi; "
            f"exec env -i {' '.join(shlex.quote(f'{k}={v}') for k, v in env.items())} "
            + " ".join(shlex.quote(a) for a in argv)
        )
        return subprocess.run([unshare, "-m", "sh", "-c", script], capture_output=True,
                              text=True, timeout=300)  # fmt: skip

    return run


def _rows(p: subprocess.CompletedProcess) -> np.ndarray:
    assert p.returncode == 0, p.stderr[-3000:]
    return np.array([[float(x) for x in line.split(",")] for line in p.stdout.splitlines()])


def test_the_namespace_really_hides_the_build_python(foreign):
    """The checks themselves: inside, the recorded libpython is gone and numpy unimportable."""
    p = foreign(["/usr/bin/python3", "-c", "import sys; print(sys.version_info[:2])"], EMPTY_ENV)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip().startswith("(3, 1")
    outside = subprocess.run(["sh", "-c", f"test -e {shlex.quote(str(libpython()))}"])
    assert outside.returncode == 0  # it exists outside


def _alone_plan(fmu_dir: Path, name: str, folder: Path) -> Path:
    fmu = fmu_dir / f"{name}.fmu"
    with zipfile.ZipFile(fmu) as z:
        z.extractall(folder)
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    inputs, outputs = ALONE[name]
    lines = [f"fmu {name} {folder} {md.coSimulation.modelIdentifier} {md.guid}"]
    lines += [f"real {name} {vr[k]} {v!r}" for k, v in inputs.items()]
    lines += [f"record {name} {vr[k]}" for k in outputs]
    lines.append(f"run 0.02 {STOP!r}")
    plan = folder / "plan.txt"
    plan.write_text("\n".join(lines) + "\n")
    return plan


@pytest.mark.parametrize(
    "name",
    ["GliderPlant", "GliderController", "GliderObserver"],
)
def test_each_fmu_alone_on_a_foreign_machine_equals_the_building_one(
    foreign, host, fmu_dir, tmp_path, name
):
    plan = _alone_plan(fmu_dir, name, tmp_path / name)
    at_home = _rows(subprocess.run([str(host), str(plan)], env=EMPTY_ENV, capture_output=True,
                                   text=True, timeout=180))  # fmt: skip
    away = foreign([str(host), str(plan)], EMPTY_ENV)
    assert away.returncode == 0, away.stderr[-3000:]
    rows = _rows(away)
    assert rows.shape == at_home.shape == (round(STOP / 0.02) + 1, 1 + len(ALONE[name][1]))
    assert np.array_equal(rows, at_home)  # bit for bit
    assert np.all(np.isfinite(rows))


def test_closed_loop_on_a_foreign_machine_equals_our_master_bit_for_bit(foreign, host, loop):
    system, plan = loop
    rows = _rows(foreign([str(host), str(plan)], EMPTY_ENV))
    ours = master_jacobi(system)
    assert rows.shape == ours.shape
    assert np.array_equal(rows, ours)  # bit for bit


def test_without_python3_on_path_the_system_libpython_is_found(foreign, host, fmu_dir, tmp_path):
    """The last place searched: libpython3.X.so.1.0 in the system's library folders."""
    plan = _alone_plan(fmu_dir, "GliderPlant", tmp_path / "plant")
    rows = _rows(foreign([str(host), str(plan)], {"PATH": "/nonexistent"}))
    assert rows.shape == (round(STOP / 0.02) + 1, 1 + len(ALONE["GliderPlant"][1]))


def test_no_usable_python_gives_one_fatal_line_naming_what_was_tried(
    foreign, host, fmu_dir, tmp_path
):
    """Every system libpython made unloadable too (/dev/null bound over it)."""
    plan = _alone_plan(fmu_dir, "GliderPlant", tmp_path / "plant")
    libs = sorted(glob.glob("/usr/lib/*/libpython3.*.so.1.0"))
    spoil = " && ".join(f"mount --bind /dev/null {shlex.quote(f)}" for f in libs)
    p = foreign([str(host), str(plan)], EMPTY_ENV, extra=spoil)
    assert p.returncode == 4, p.stderr[-2000:]  # fmi2Instantiate returned NULL
    lines = [x for x in p.stderr.splitlines() if "logStatusFatal" in x]
    assert len(lines) == 1, p.stderr
    line = lines[0]
    assert "Python is not available: no usable Python 3.11 or later; tried: recorded " in line
    assert f"{libpython()}: not found" in line
    assert "python3 on PATH (/usr/bin/python3): " in line and "cannot load /usr/lib/" in line, line
    assert "GLIDER_FMI_PYTHON_CONFIG" in line
