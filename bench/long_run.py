"""Reliability benchmark: a long run (default 1 h of simulated time at 50 Hz) of the
default scenario streamed to CSV; reports wall time, rows and peak resident memory.

Usage: python bench/long_run.py [--hours 1] [--json]
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

from _common import emit

from glider_cosim.runner import simulate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--fmu-dir", default="fmus")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rss = []
    with tempfile.TemporaryDirectory() as tmp:
        # a short run first: memory after loading everything
        simulate(None, Path(tmp) / "short", fmu_dir=args.fmu_dir, stop_time=60.0, plots=False)
        rss.append(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        t0 = time.perf_counter()
        r = simulate(None, Path(tmp) / "long", fmu_dir=args.fmu_dir,
                     stop_time=3600.0 * args.hours, plots=False)  # fmt: skip
        wall = time.perf_counter() - t0
        rss.append(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        size = (Path(tmp) / "long" / "results.csv").stat().st_size
    result = {
        "simulated_s": 3600.0 * args.hours,
        "rows": int(r.metrics["rows"]),
        "status": r.status,
        "wall_s": round(wall, 1),
        "csv_mib": round(size / 2**20, 1),
        "peak_rss_after_60s_run_mib": round(rss[0], 1),
        "peak_rss_after_long_run_mib": round(rss[1], 1),
        "note": "peak RSS includes reading the CSV back into the returned array",
    }
    emit(result, args.json)


if __name__ == "__main__":
    main()
