"""Reliability benchmark: N instantiate/initialise/step/reset/free cycles of the three
FMUs in one process; reports resident memory (RSS) growth.

Usage: python bench/repeated_use.py [--cycles 1000] [--json]
"""

from __future__ import annotations

import time
from pathlib import Path

from _common import emit, parse_args, rss_mib

from glider_cosim.fmus.folders import build_all
from glider_cosim.master import CoSimulation
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for


def cycle(fmu_dir: Path, sc) -> None:
    sim = CoSimulation(system_for(sc, fmu_dir))
    try:
        sim.initialize()
        for _ in range(10):
            sim.communication_point()
            sim.do_step()
        sim.reset({"controller": {"K_c": 12.0}})
        for _ in range(10):
            sim.communication_point()
            sim.do_step()
    finally:
        sim.close()


def main() -> None:
    args = parse_args(__doc__, ("--cycles", {"type": int, "default": 1000}))
    fmu_dir = Path(args.fmu_dir)
    build_all(fmu_dir, only_stale=True)
    sc = load_scenario(None)
    warm = min(50, args.cycles // 10)
    for _ in range(warm):
        cycle(fmu_dir, sc)
    rss0 = rss_mib()
    t0 = time.perf_counter()
    marks = {}
    for i in range(warm, args.cycles):
        cycle(fmu_dir, sc)
        if (i + 1) % max(1, args.cycles // 4) == 0:
            marks[i + 1] = round(rss_mib(), 1)
    rss1 = rss_mib()
    n = args.cycles - warm
    result = {
        "cycles": args.cycles,
        "fmus_per_cycle": 3,
        "rss_after_warmup_mib": round(rss0, 1),
        "rss_end_mib": round(rss1, 1),
        "growth_kib_per_cycle": round((rss1 - rss0) * 1024 / max(n, 1), 2),
        "rss_marks_mib": marks,
        "ms_per_cycle": round((time.perf_counter() - t0) / max(n, 1) * 1e3, 1),
    }
    emit(result, args.json)


if __name__ == "__main__":
    main()
