"""The master's time per macro step of the default scenario, native run in memory.

Usage: python bench/master_step.py FMU_DIR [--repeat N]
Prints the best of ``--repeat`` runs of ``CoSimulation.run`` (rows in memory,
initialisation not included) in microseconds per macro step, as
``bench/cosim_step.py``'s ``native_us_per_macro_step``. It imports only the public API,
so another install can run it too: alternate two interpreters in one shell loop to
compare them under the same load, e.g.::

    for i in $(seq 15); do echo $(OLD/bin/python bench/master_step.py DIR) \\
        $(NEW/bin/python bench/master_step.py DIR); done
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from glider_cosim.master import CoSimulation
from glider_cosim.runner.recorders import ArrayRecorder
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fmu_dir", type=Path, help="the native FMUs")
    ap.add_argument("--repeat", type=int, default=10, help="runs; the best is kept")
    args = ap.parse_args()
    sc = load_scenario(None)
    n = round(sc.stop_time / sc.step)
    best = float("inf")
    for _ in range(args.repeat):
        sim = CoSimulation(system_for(sc, args.fmu_dir), step=sc.step, coupling=sc.coupling)
        try:
            sim.initialize()
            t0 = time.perf_counter()
            sim.run(sc.stop_time, ArrayRecorder())
            best = min(best, (time.perf_counter() - t0) / n)
        finally:
            sim.close()
    print(f"{best * 1e6:.3f}")


if __name__ == "__main__":
    main()
