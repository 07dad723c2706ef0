"""The C host of tests/integration/c_host (host.c) for the tests that run it: compiled
against the FMI headers fmpy ships, its plan written from a system, run as it is, with no
Python reachable (a mount namespace), under wine or under valgrind; and our master's
Jacobi run the hosts' results are compared with.

Used by test_c_host.py, test_native.py and test_fmi3.py (FMI 3: ``-DGLIDER_HOST_FMI3``).
"""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy import read_model_description
from system_tools import require_tool, tool_missing

from glider_cosim.fmus.native import MINGW
from glider_cosim.master import CoSimulation
from glider_cosim.runner.recorders import ArrayRecorder

HOST_C = Path(__file__).parent / "c_host" / "host.c"
HEADERS = Path(fmpy.__file__).parent / "c-code"
RECORD = ["plant.theta_g", "plant.V", "plant.delta", "observer.theta_g_hat", "controller.delta_cmd"]
STOP = 10.0
#: what gcc needs besides the common flags to build the host for linux64
GCC_FLAGS = ["-D_DEFAULT_SOURCE", "-ldl", "-lm", "-lpthread"]


def unzip(fmu: Path, where: Path) -> Path:
    with zipfile.ZipFile(fmu) as z:
        z.extractall(where)
    return where


def compile_host(compiler: str | list[str], out: Path, extra: list[str]) -> Path:
    start = [compiler] if isinstance(compiler, str) else list(compiler)
    if not Path(start[0]).is_absolute():  # a system compiler (zig's is a path)
        require_tool(start[0])
    p = subprocess.run([*start, "-std=c99", "-Wall", "-Wextra", "-Werror", "-O1",
                        f"-I{HEADERS}", "-o", str(out), str(HOST_C), *extra],
                       capture_output=True, text=True)  # fmt: skip
    assert p.returncode == 0, p.stderr
    return out


def write_plan(system, root: Path, dir_of=str, threads: bool = False, step: float = 0.02) -> Path:
    """The C host's plan for ``system`` (its FMUs unzipped under ``root``): ``RECORD``
    recorded, steps of ``step`` to ``STOP``."""
    lines, mds = [], {}
    for inst, fmu in system.fmus.items():
        folder = unzip(fmu, root / inst)
        md = mds[inst] = read_model_description(str(fmu))
        lines.append(f"fmu {inst} {dir_of(folder)} {md.coSimulation.modelIdentifier} {md.guid}")
    vars_ = {i: {v.name: v for v in md.modelVariables} for i, md in mds.items()}
    for inst, params in system.parameters.items():
        for name, value in params.items():
            v = vars_[inst][name]
            kind = {"Real": "real", "Integer": "integer", "Float64": "real", "Int32": "integer"}[
                v.type
            ]
            lines.append(f"{kind} {inst} {v.valueReference} {float(value)!r}")
    for src, dst in system.connections:
        (si, sn), (di, dn) = src.split("."), dst.split(".")
        lines.append(
            f"connect {si} {vars_[si][sn].valueReference} {di} {vars_[di][dn].valueReference}"
        )  # noqa: E501
    for ref in RECORD:
        i, n = ref.split(".")
        lines.append(f"record {i} {vars_[i][n].valueReference}")
    lines.append(f"run {step!r} {STOP!r}")
    if threads:
        lines.append("threads")
    plan = root / "plan.txt"
    plan.write_text("\n".join(lines) + "\n")
    return plan


def rows(text: str) -> np.ndarray:
    return np.array([[float(x) for x in line.split(",")] for line in text.splitlines() if line])


def master_jacobi_run(system) -> ArrayRecorder:
    """Our master's Jacobi run of ``system`` at 50 Hz to ``STOP``, recording ``RECORD``."""
    system.record = list(RECORD)
    sim = CoSimulation(system, step=0.02, coupling="jacobi")
    rec = ArrayRecorder()
    try:
        sim.run(STOP, rec)
    finally:
        sim.close()
    return rec


def python_places() -> list[str]:
    """Folders that hold a Python installation or packages (hidden in the namespace)."""
    places = {sys.base_prefix, sys.prefix, "/usr/lib/python3", "/usr/local/lib/python3.11"}
    places.update(str(p) for p in Path("/usr/lib").glob("python3*"))
    pyenv = Path(sys.base_prefix).parents
    places.update(str(p) for p in pyenv if p.name in (".pyenv", "versions"))
    return sorted(p for p in places if Path(p).is_dir())


def hidden_run(host: Path, plan: Path, tmp_path: Path) -> subprocess.CompletedProcess:
    """``host plan`` under unshare -m with tmpfs over every Python folder and /dev/null over
    every libpython, after checking that no Python can start there."""
    require_tool("unshare", install="apt-get install util-linux")
    probe = subprocess.run(["unshare", "-m", "true"], capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"unshare -m is not permitted here: {probe.stderr.strip()}")
    mounts = []
    for place in sorted(python_places(), key=len):  # parents first: children then skipped
        if any(place.startswith(m + "/") for m in mounts):
            continue
        mounts.append(place)
    libs = sorted({str(p.resolve()) for p in Path("/usr/lib/x86_64-linux-gnu").glob("libpython3*")
                   if p.resolve().is_file()})  # fmt: skip
    script = "set -e\n"
    script += "".join(f"mount --bind /dev/null '{lib}'\n" for lib in libs)
    script += "".join(f"mount -t tmpfs none '{m}'\n" for m in mounts)
    # Python must really be gone: no python3 starts, the build interpreter is not there
    script += (
        f"if [ -e '{sys.executable}' ]; then echo 'build python visible' >&2; exit 90; fi\n"
        "for py in python3 python3.11 python; do\n"
        "  if env -i PATH=/usr/bin:/bin:/usr/local/bin $py -c pass 2>/dev/null; then\n"
        '    echo "$py starts" >&2; exit 91; fi\n'
        "done\n"
        f"exec env -i PATH=/usr/bin:/bin '{host}' '{plan}'\n"
    )
    return subprocess.run(["unshare", "-m", "sh", "-c", script], capture_output=True,
                          text=True, timeout=300)  # fmt: skip


def hidden_rows(system, tmp_path: Path, host_name: str, extra: list[str], threads: bool = False):
    """The rows of the host (gcc, ``extra`` flags) run on ``system`` with no Python
    reachable (:func:`hidden_run`); the run must succeed."""
    host = compile_host("gcc", tmp_path / host_name, [*extra, *GCC_FLAGS])
    plan = write_plan(system, tmp_path, threads=threads)
    p = hidden_run(host, plan, tmp_path)
    assert p.returncode == 0, p.stderr[-2000:]
    return rows(p.stdout)


def wine_env(tmp_path: Path) -> dict[str, str]:
    require_tool("wine", install="apt-get install wine64 wine")
    (tmp_path / "winetmp").mkdir()
    return {**os.environ, "WINEPREFIX": str(tmp_path / "wineprefix"), "WINEDEBUG": "-all",
            "TMPDIR": str(tmp_path / "winetmp"),
            "WINEDLLOVERRIDES": "mscoree,mshtml="}  # fmt: skip


def wine_rows(system, tmp_path: Path, host_name: str, extra: list[str]) -> np.ndarray:
    """The rows of the host cross-compiled with mingw-w64 (``extra`` flags) run under wine
    on ``system``'s win64 DLLs; the run must succeed."""
    require_tool(MINGW, install="apt-get install gcc-mingw-w64-x86-64")
    host = compile_host(MINGW, tmp_path / host_name, list(extra))
    plan = write_plan(system, tmp_path, dir_of=lambda p: "Z:" + str(p))
    env = wine_env(tmp_path)
    try:
        p = subprocess.run(["wine", str(host), "Z:" + str(plan)], capture_output=True,
                           text=True, timeout=600, env=env)  # fmt: skip
    finally:
        subprocess.run(["wineserver", "-k"], env=env, capture_output=True, timeout=60)
    assert p.returncode == 0, p.stderr[-2000:]
    return rows(p.stdout.replace("\r", ""))


#: qemu-user's aarch64 emulator and the sysroot of Debian's libc6-arm64-cross
QEMU = "qemu-aarch64"
AARCH64_SYSROOT = "/usr/aarch64-linux-gnu"


def qemu_rows(system, tmp_path: Path, host_name: str, extra: list[str]) -> np.ndarray:
    """The rows of the host built for aarch64 Linux by zig (``extra`` flags), run under
    qemu-user on ``system``'s ``binaries/aarch64-linux`` libraries; the run must succeed."""
    from glider_fmi import toolchain

    require_tool(QEMU, install="apt-get install qemu-user")
    if not Path(AARCH64_SYSROOT, "lib").is_dir():
        tool_missing(f"{AARCH64_SYSROOT} is missing (apt-get install libc6-arm64-cross; "
                     ".ci/run installs it)")  # fmt: skip
    zig = [*toolchain.zig_command(), "-target", toolchain.PLATFORMS["aarch64-linux"].zig_target]
    host = compile_host(zig, tmp_path / host_name, [*extra, *GCC_FLAGS])
    require_tool("readelf", install="apt-get install binutils")
    machine = subprocess.run(["readelf", "-h", str(host)], capture_output=True, text=True,
                             check=True).stdout  # fmt: skip
    assert "AArch64" in machine  # really an aarch64 program
    plan = write_plan(system, tmp_path)
    p = subprocess.run([QEMU, "-L", AARCH64_SYSROOT, str(host), str(plan)], capture_output=True,
                       text=True, timeout=600)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    return rows(p.stdout)


def valgrind_run(system, tmp_path: Path, host_name: str, extra: list[str]):
    """The host (gcc -g, ``extra`` flags) run under valgrind memcheck on ``system``, one
    thread per step."""
    require_tool("valgrind")
    host = compile_host("gcc", tmp_path / host_name, [*extra, "-D_DEFAULT_SOURCE", "-g", "-ldl",
                                                      "-lm", "-lpthread"])  # fmt: skip
    plan = write_plan(system, tmp_path, threads=True)
    return subprocess.run(["valgrind", "--error-exitcode=99", "--leak-check=full",
                           "--errors-for-leak-kinds=definite", "--track-origins=yes",
                           str(host), str(plan)], capture_output=True, text=True,
                          timeout=600)  # fmt: skip
