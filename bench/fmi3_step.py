"""Benchmark: the default scenario (60 s, 3000 macro steps, in memory) through our master
on the FMI 2.0 and the FMI 3.0 build of a flavor: load + initialise, and the stepping.

Usage: python bench/fmi3_step.py [--flavor native|python] [--runs N]

Builds both sets into a temporary folder, then runs them interleaved (N runs each after
one warm-up) and prints the medians. The stepping goes through the C fast loop on both
(for FMI 3 through the shims of ``cosim/master/fastloop.c``).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from glider_cosim.fmus.fmi3 import build_fmi3
from glider_cosim.fmus.folders import build_all
from glider_cosim.master import CoSimulation
from glider_cosim.runner.recorders import ArrayRecorder
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for


def one_run(sc, folder: Path) -> tuple[float, float, bool]:
    t0 = time.perf_counter()
    sim = CoSimulation(system_for(sc, folder), step=0.02)
    rec = ArrayRecorder()
    sim.initialize()
    rec.start(sim.columns)
    rec.row(sim.communication_point())
    t1 = time.perf_counter()
    sim.advance(3000, rec)
    t2 = time.perf_counter()
    fast = sim._fast is not None
    sim.close()
    return t1 - t0, t2 - t1, fast


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--flavor", choices=("native", "python"), default="native")
    ap.add_argument("--runs", type=int, default=15)
    args = ap.parse_args()
    sc = load_scenario("default")
    with tempfile.TemporaryDirectory() as tmp:
        sets = {"FMI 2": Path(tmp) / "fmi2", "FMI 3": Path(tmp) / "fmi3"}
        build_all(sets["FMI 2"], flavor=args.flavor)
        build_fmi3(sets["FMI 3"], args.flavor)
        times: dict[str, list[tuple[float, float]]] = {k: [] for k in sets}
        for i in range(args.runs + 1):
            for name, folder in sets.items():
                setup, step, fast = one_run(sc, folder)
                assert fast, f"{name}: the C fast loop did not run"
                if i:
                    times[name].append((setup, step))
        for name, ts in times.items():
            setup = statistics.median(t[0] for t in ts) * 1e3
            step = statistics.median(t[1] for t in ts) / 3000 * 1e6
            print(f"{args.flavor} {name}: load+init {setup:.1f} ms, {step:.2f} us per macro step "
                  f"(median of {args.runs})")  # fmt: skip


if __name__ == "__main__":
    main()
