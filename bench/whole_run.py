"""A whole ``glider-cosim run --no-plots``, process start to exit, against ``python3 -c pass``.

Each figure is the median wall time (s) of ``--repeat`` new processes; the commands are
interleaved (``python -c pass``, then each run) so the machine's load weighs on each
alike. ``over_pass_s`` is a run's median minus the interpreter's: what glider-cosim adds
to starting Python (issue 48's target: at most 0.10 s for the native flavor). The FMU
cache is warm (a first run builds it before the timing); the interpreter may write its
bytecode (as a ``pip install`` compiles it), whatever ``PYTHONDONTWRITEBYTECODE`` says.
``--python`` (repeatable) times the commands with other interpreters too, e.g. a venv of
another checkout, for before and after figures in one session: each gets its own
``python -c pass`` figure.

Usage: python bench/whole_run.py [--repeat 21] [--flavor native --flavor python]
       [--python PY ...] [--json]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import emit


def _command(python: str) -> list[str]:
    """The ``glider-cosim`` console script beside ``python`` (what a user runs), else the
    module."""
    script = Path(python).parent / "glider-cosim"
    return [str(script)] if script.exists() else [python, "-m", "glider_cosim.cli"]


def timed(cmd: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Seconds ``cmd`` takes in a new process: wall time, and CPU time (user and system,
    less swayed by the machine's load).

    Raises
    ------
    RuntimeError
        The command failed (its last error lines quoted).
    """
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    seconds = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed (exit {p.returncode}): {p.stderr[-500:]}")
    return seconds, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=21, help="processes per figure (median)")
    ap.add_argument("--flavor", action="append", choices=["native", "python"],
                    help="the runs timed (default: native and python)")  # fmt: skip
    ap.add_argument("--python", action="append", help="interpreters (default: this one)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    flavors = args.flavor or ["native", "python"]
    pythons = args.python or [sys.executable]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    times: dict[str, list[tuple[float, float]]] = {}
    with tempfile.TemporaryDirectory(prefix="whole_run_") as tmp:
        runs = {}
        for i, py in enumerate(pythons):
            label = "" if len(pythons) == 1 else f"{i}_"
            runs[f"{label}pass"] = [py, "-c", "pass"]
            for flavor in flavors:
                out = str(Path(tmp) / f"{i}_{flavor}")
                runs[f"{label}{flavor}"] = [*_command(py), "run", "--no-plots", "--flavor",
                                            flavor, "--out", out]  # fmt: skip
        for cmd in runs.values():  # the FMU cache built, the bytecode written
            timed(cmd, env)
        load = os.getloadavg()
        for _ in range(args.repeat):
            for name, cmd in runs.items():
                times.setdefault(name, []).append(timed(cmd, env))
    result: dict[str, object] = {"repeat": args.repeat, "load_avg_1min": round(load[0], 2)}
    for i, py in enumerate(pythons):
        label = "" if len(pythons) == 1 else f"{i}_"
        if label:
            result[f"{label}python"] = py
        for kind, k in (("", 0), ("cpu_", 1)):
            base = statistics.median(t[k] for t in times[f"{label}pass"])
            result[f"{label}python_pass_{kind}s"] = round(base, 4)
            for flavor in flavors:
                median = statistics.median(t[k] for t in times[f"{label}{flavor}"])
                result[f"{label}run_{flavor}_{kind}s"] = round(median, 4)
                result[f"{label}run_{flavor}_over_pass_{kind}s"] = round(median - base, 4)
    emit(result, args.json)


if __name__ == "__main__":
    main()
