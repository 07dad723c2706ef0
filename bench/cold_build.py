"""Cold builds of the native FMUs: the first ``glider-cosim run --flavor native`` and
``glider-cosim build --flavor native`` (every platform), each into a fresh FMU cache.

Each figure is the median wall time (s) of ``--repeat`` runs of the command in a new
process, into a new temporary ``$GLIDER_COSIM_CACHE``; the ``*_zig_cold_s`` ones also
with a new ``$ZIG_GLOBAL_CACHE_DIR`` (a fresh machine: zig builds each target's C
library pieces first), ``--zig-cold-repeat`` times. ``--python`` runs the commands with
another interpreter (e.g. a venv of another checkout, for before and after figures in
one session).

Usage: python bench/cold_build.py [--repeat 3] [--zig-cold-repeat 1] [--no-zig-cold]
       [--python PY] [--json]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import emit

#: the commands timed: name -> glider-cosim arguments (``{out}``: a temporary folder)
COMMANDS = {
    "cold_run_native": ["run", "--flavor", "native", "--out", "{out}"],
    "cold_run_native_no_plots": ["run", "--flavor", "native", "--no-plots", "--out", "{out}"],
    "build_native_all": ["build", "--flavor", "native", "--out", "{out}"],
}


def timed(python: str, args: list[str], zig_cold: bool) -> float:
    """Seconds one ``glider-cosim`` command takes in a new process, into a fresh FMU cache
    (and a fresh zig cache if ``zig_cold``).

    Raises
    ------
    RuntimeError
        The command failed (its last error lines quoted).
    """
    with tempfile.TemporaryDirectory(prefix="cold_build_") as tmp:
        env = {**os.environ, "GLIDER_COSIM_CACHE": str(Path(tmp) / "cache")}
        if zig_cold:
            env["ZIG_GLOBAL_CACHE_DIR"] = str(Path(tmp) / "zig")
        cmd = [python, "-m", "glider_cosim.cli", *(a.format(out=Path(tmp) / "out") for a in args)]
        t = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=1800)
        seconds = time.perf_counter() - t
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed (exit {p.returncode}): {p.stderr[-500:]}")
    return seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs per figure (median; 0 skips)")
    ap.add_argument("--zig-cold-repeat", type=int, default=1, help="runs per zig-cold figure")
    ap.add_argument("--no-zig-cold", action="store_true", help="skip the zig-cold figures")
    ap.add_argument("--python", default=sys.executable, help="interpreter running glider-cosim")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    result: dict[str, object] = {"python": args.python, "load_before": os.getloadavg()[0]}
    variants = [(False, args.repeat)] + [(True, args.zig_cold_repeat)] * (not args.no_zig_cold)
    for zig_cold, repeat in (v for v in variants if v[1] > 0):  # 0: skip
        for name, cmd in COMMANDS.items():
            times = [timed(args.python, cmd, zig_cold) for _ in range(repeat)]
            key = f"{name}{'_zig_cold' if zig_cold else ''}_s"
            result[key] = round(statistics.median(times), 2)
            result[key.removesuffix("_s") + "_runs_s"] = [round(t, 2) for t in times]
    result["load_after"] = os.getloadavg()[0]
    emit(result, args.json)


if __name__ == "__main__":
    main()
