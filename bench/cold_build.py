"""Cold builds: the first ``glider-cosim run`` (the default, Python flavor), the first
``glider-cosim run --flavor native`` and ``glider-cosim build --flavor native`` (every
platform), each into a fresh FMU cache.

Each figure is the median wall time (s) of ``--repeat`` runs of the command in a new
process, into a new temporary ``$GLIDER_COSIM_CACHE`` and, by default, a new
``$ZIG_GLOBAL_CACHE_DIR`` too: what a new user waits for (zig builds each target's C
library pieces first, Windows' MinGW runtime the longest). ``--zig-warm-repeat N`` adds
the ``*_zig_warm_s`` figures, with zig's own cache (as it is on this machine, warmed by
one build first): a new FMU cache on a machine that has built before. ``--python``
(repeatable) runs the commands with other interpreters (e.g. a venv of another
checkout), each command with each in turn: before and after figures in one session.

``--command`` (repeatable) times only those named. ``--keep DIR`` runs every command in
``DIR/cache`` and ``DIR/zig`` (emptied before each run: the same paths for every
interpreter, which the binaries' debug information names) and keeps what each wrote in
``DIR/<command>-<interpreter>-<run>``; with two interpreters, ``differing_members``
lists the FMU members (``<command>/<fmu>/<member>``) of their last runs whose
:func:`digest` differs. Each ``*_s`` figure has a
``*_cpu_s`` beside it: the CPU time (user + system) of the command and every process it
waited for (zig's compiles), the median of the same runs; on this shared machine it moves
less with the load than the wall time.

Usage: python bench/cold_build.py [--repeat 1] [--zig-warm-repeat 0] [--python PY ...]
       [--command NAME ...] [--json]
"""

from __future__ import annotations

import argparse
import hashlib
import os
import resource
import shutil
import statistics
import struct
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

from _common import emit

#: the commands timed: name -> glider-cosim arguments (``{out}``: a temporary folder)
COMMANDS = {
    "cold_run": ["run", "--out", "{out}"],
    "cold_run_native": ["run", "--flavor", "native", "--out", "{out}"],
    "cold_run_native_no_plots": ["run", "--flavor", "native", "--no-plots", "--out", "{out}"],
    "build_native_all": ["build", "--flavor", "native", "--out", "{out}"],
}


def _pe_normalized(data: bytes) -> bytes:
    """A PE file (a Windows DLL) with the fields lld's ``/Brepro`` fills with hashes of the
    PDB and of the file zeroed: the COFF header's and each debug directory entry's
    TimeDateStamp and the CodeView record's GUID. The PDB names the paths of the link's
    inputs and the random temporary names of zig's MinGW objects, so these differ between
    any two builds from an empty zig cache; anything else is kept. Other files unchanged."""
    if data[:2] != b"MZ":
        return data
    b = bytearray(data)
    coff = struct.unpack_from("<I", b, 0x3C)[0] + 4
    sections = struct.unpack_from("<H", b, coff + 2)[0]
    optional_size = struct.unpack_from("<H", b, coff + 16)[0]
    struct.pack_into("<I", b, coff + 4, 0)
    optional = coff + 20
    debug_rva, debug_size = struct.unpack_from("<II", b, optional + 112 + 6 * 8)

    def offset(rva: int) -> int:
        for i in range(sections):
            vsize, va, rsize, raw = struct.unpack_from(
                "<IIII", b, optional + optional_size + 40 * i + 8
            )
            if va <= rva < va + max(vsize, rsize):
                return raw + rva - va
        raise ValueError(f"RVA {rva:#x} in no section")

    if debug_size:
        first = offset(debug_rva)
        for entry in range(first, first + debug_size - 27, 28):
            struct.pack_into("<I", b, entry + 4, 0)
            kind, pointer = (
                struct.unpack_from("<I", b, entry + 12)[0],
                struct.unpack_from("<I", b, entry + 24)[0],
            )
            if kind == 2 and b[pointer : pointer + 4] == b"RSDS":
                b[pointer + 4 : pointer + 20] = bytes(16)
    return bytes(b)


def digest(folder: Path) -> dict[str, str]:
    """SHA-256 of every member of the FMUs in ``folder`` (``<fmu>/<member>``), each Windows
    DLL's build hashes zeroed (:func:`_pe_normalized`)."""
    out = {}
    for fmu in sorted(folder.glob("*.fmu")):
        with zipfile.ZipFile(fmu) as z:
            for name in z.namelist():
                data = _pe_normalized(z.read(name))
                out[f"{fmu.name}/{name}"] = hashlib.sha256(data).hexdigest()
    return out


def timed(
    python: str, args: list[str], zig_cold: bool, keep: Path | None = None, label: str = ""
) -> tuple[float, float]:
    """Seconds one ``glider-cosim`` command takes in a new process, into a fresh FMU cache
    (and a fresh zig cache if ``zig_cold``): wall time and CPU time (user + system of the
    process and of every one it waited for). ``keep``: the caches in ``keep`` (emptied
    first), the output kept in ``keep/label``.

    Raises
    ------
    RuntimeError
        The command failed (its last error lines quoted).
    """
    with tempfile.TemporaryDirectory(prefix="cold_build_") as tmp:
        home = keep or Path(tmp)
        out = keep / label if keep else Path(tmp) / "out"
        if keep:
            for folder in (keep / "cache", keep / "zig", out):
                shutil.rmtree(folder, ignore_errors=True)
        env = {**os.environ, "GLIDER_COSIM_CACHE": str(home / "cache")}
        if zig_cold:
            env["ZIG_GLOBAL_CACHE_DIR"] = str(home / "zig")
        cmd = [python, "-m", "glider_cosim.cli", *(a.format(out=out) for a in args)]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=1800)
        seconds = time.perf_counter() - t
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed (exit {p.returncode}): {p.stderr[-500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return seconds, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1,
                    help="runs per figure, zig's cache empty too (median; 0 skips)")  # fmt: skip
    ap.add_argument("--zig-warm-repeat", type=int, default=0,
                    help="runs per figure with zig's cache warm (0: none)")  # fmt: skip
    ap.add_argument("--python", action="append",
                    help="interpreter running glider-cosim (repeatable: each command is "
                         "timed with each in turn, interleaved)")  # fmt: skip
    ap.add_argument("--command", action="append", choices=list(COMMANDS),
                    help="the commands timed (default: every one)")  # fmt: skip
    ap.add_argument("--keep", type=Path,
                    help="run in DIR/cache and DIR/zig, keep each output in DIR")  # fmt: skip
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    pythons = args.python or [sys.executable]
    commands = {k: v for k, v in COMMANDS.items() if k in (args.command or COMMANDS)}
    result: dict[str, object] = {"python": pythons if len(pythons) > 1 else pythons[0],
                                 "load_before": os.getloadavg()[0]}  # fmt: skip
    if args.zig_warm_repeat > 0:  # zig's cache warmed for these interpreters' sources
        for py in pythons:
            timed(py, COMMANDS["build_native_all"], zig_cold=False)
    for zig_cold, repeat in ((True, args.repeat), (False, args.zig_warm_repeat)):
        for name, cmd in commands.items() if repeat > 0 else ():
            times: dict[int, list[tuple[float, float]]] = {i: [] for i in range(len(pythons))}
            for _ in range(repeat):
                for i, py in enumerate(pythons):
                    label = f"{name}-{i}-{len(times[i])}"
                    times[i].append(timed(py, cmd, zig_cold, args.keep, label))
            for i in times:
                prefix = f"{i}_" if len(pythons) > 1 else ""
                key = f"{prefix}{name}_zig_{'cold' if zig_cold else 'warm'}_s"
                walls = [t for t, _ in times[i]]
                cpus = [c for _, c in times[i]]
                result[key] = round(statistics.median(walls), 2)
                result[key.removesuffix("_s") + "_runs_s"] = [round(t, 2) for t in walls]
                result[key.removesuffix("_s") + "_cpu_s"] = round(statistics.median(cpus), 2)
            if args.keep and len(pythons) == 2:
                last = [digest(args.keep / f"{name}-{i}-{repeat - 1}") for i in range(2)]
                result.setdefault("differing_members", []).extend(
                    f"{name}/{m}" for m in sorted(set(last[0]) | set(last[1]))
                    if last[0].get(m) != last[1].get(m)
                )  # fmt: skip
    result["load_after"] = os.getloadavg()[0]
    emit(result, args.json)


if __name__ == "__main__":
    main()
