"""Whole runs, process start to exit, beside fmpy's own command line on one FMU.

Each figure is the median wall time (s), and CPU time (user and system, less swayed by
the machine's load), of ``--repeat`` new processes; the commands are interleaved (one
of each per round) so the machine's load weighs on each alike:

- ``python -c pass``: the interpreter alone;
- per flavor: ``glider-cosim run --no-plots --flavor F`` (three FMUs, results.csv and
  metrics.json), ``glider-cosim run --flavor F`` (the same with the PNG plots and
  plots.html), and ``fmpy simulate GliderPlant.fmu --stop-time 60 --output-interval
  0.02`` (fmpy's own CLI, one FMU of the same flavor from the same FMU cache, inputs
  open, 3000 steps, its CSV written).

No target: the figures say what a user waits for. The FMU cache is warm (a first round,
not timed, builds it and writes the bytecode). ``--python`` (repeatable) times the
commands with other interpreters too, e.g. a venv of another checkout, for before and
after figures in one session.

Usage: python bench/whole_run.py [--repeat 11] [--flavor native --flavor python]
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


def _command(python: str, name: str, module: str) -> list[str]:
    """The console script ``name`` beside ``python`` (what a user runs), else
    ``python -m module``."""
    script = Path(python).parent / name
    return [str(script)] if script.exists() else [python, "-m", module]


def fmu_folder(python: str, flavor: str) -> Path:
    """The FMU cache's folder of ``flavor`` for ``python``'s glider-cosim (built if stale)."""
    code = ("from glider_cosim.fmus.folders import prepare_fmus; "
            f"print(prepare_fmus(None, {flavor!r}))")  # fmt: skip
    out = subprocess.run([python, "-c", code], capture_output=True, text=True, check=True)
    return Path(out.stdout.strip().splitlines()[-1])


def timed(cmd: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Seconds ``cmd`` takes in a new process: wall time, and CPU time (user and system).

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
    ap.add_argument("--repeat", type=int, default=11, help="processes per figure (median)")
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
            cli = _command(py, "glider-cosim", "glider_cosim.cli")
            fmpy = _command(py, "fmpy", "fmpy.command_line")
            for flavor in flavors:
                out = str(Path(tmp) / f"{i}_{flavor}")
                run = [*cli, "run", "--flavor", flavor, "--out", out]
                runs[f"{label}run_{flavor}_no_plots"] = [*run[:2], "--no-plots", *run[2:]]
                runs[f"{label}run_{flavor}_plots"] = run
                plant = fmu_folder(py, flavor) / "GliderPlant.fmu"
                runs[f"{label}fmpy_simulate_{flavor}"] = [
                    *fmpy, "simulate", str(plant), "--stop-time", "60", "--output-interval",
                    "0.02", "--output-file", str(Path(tmp) / f"{i}_{flavor}_fmpy.csv"),
                ]  # fmt: skip
        for cmd in runs.values():  # the FMU cache built, the bytecode written
            timed(cmd, env)
        load = os.getloadavg()
        for _ in range(args.repeat):
            for name, cmd in runs.items():
                times.setdefault(name, []).append(timed(cmd, env))
        load_after = os.getloadavg()
    result: dict[str, object] = {
        "repeat": args.repeat,
        "load_avg_1min": [round(load[0], 2), round(load_after[0], 2)],
        "cpus": os.cpu_count(),
    }
    for i, py in enumerate(pythons):
        if len(pythons) > 1:
            result[f"{i}_python"] = py
    for name, samples in times.items():
        result[f"{name}_s"] = round(statistics.median(t[0] for t in samples), 3)
        result[f"{name}_cpu_s"] = round(statistics.median(t[1] for t in samples), 3)
    emit(result, args.json)


if __name__ == "__main__":
    main()
