"""Reliability benchmark: a long run (default 1 h of simulated time at 50 Hz) of the
default scenario streamed to CSV; reports wall time, rows and peak resident memory.

Usage: python bench/long_run.py [--hours 1] [--json]
"""

from __future__ import annotations

import resource
import tempfile
import threading
import time
from pathlib import Path

from _common import emit, parse_args, rss_mib

from glider_cosim.runner import simulate


def main() -> None:
    args = parse_args(__doc__, ("--hours", {"type": float, "default": 1.0}))
    rss = []
    with tempfile.TemporaryDirectory() as tmp:
        # a short run first: memory after loading everything
        simulate(None, Path(tmp) / "short", fmu_dir=args.fmu_dir, stop_time=60.0, plots=False)
        rss.append(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        samples: list[tuple[float, float]] = []  # (rows written, RSS MiB) while running
        csv = Path(tmp) / "long" / "results.csv"
        stop = threading.Event()

        def watch() -> None:
            while not stop.wait(0.25):
                rows = csv.stat().st_size if csv.exists() else 0
                samples.append((rows, rss_mib()))

        watcher = threading.Thread(target=watch, daemon=True)
        watcher.start()
        t0 = time.perf_counter()
        r = simulate(None, Path(tmp) / "long", fmu_dir=args.fmu_dir,
                     stop_time=3600.0 * args.hours, plots=False)  # fmt: skip
        wall = time.perf_counter() - t0
        stop.set()
        watcher.join()
        # streaming phase: from 10 % to 95 % of the final CSV size
        size_end = csv.stat().st_size
        during = [m for n, m in samples if 0.1 * size_end <= n <= 0.95 * size_end]
        rss.append(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        size = (Path(tmp) / "long" / "results.csv").stat().st_size
    result = {
        "simulated_s": 3600.0 * args.hours,
        "rows": int(r.metrics["rows"]),
        "status": r.status,
        "wall_s": round(wall, 1),
        "csv_mib": round(size / 2**20, 1),
        "rss_while_streaming_min_max_mib": [round(min(during), 1), round(max(during), 1)]
        if during
        else None,
        "peak_rss_after_60s_run_mib": round(rss[0], 1),
        "peak_rss_after_long_run_mib": round(rss[1], 1),
        "note": "peak RSS includes reading the CSV back for metrics and the returned array",
    }
    emit(result, args.json)


if __name__ == "__main__":
    main()
