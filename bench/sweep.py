"""Benchmark: runs/s of the default 60 s scenario on a local Dask cluster of 1 and 2
worker processes (K_c list), and the scaling efficiency from 1 to 2 workers.

Usage: python bench/sweep.py [--runs 24] [--json]
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

from _common import emit

from glider_cosim.build import build_all
from glider_cosim.scenario import load_scenario
from glider_cosim.sweep import expand, make_client, parse_param, run_sweep


def rate(workers: int, runs: int, fmu_dir: Path) -> float:
    sc = load_scenario(None)
    specs = [parse_param(f"controller.K_c=8:40:{runs}")]
    points = expand(specs, sc, fmu_dir)
    client = make_client(workers)
    try:
        client.wait_for_workers(workers)
        with tempfile.TemporaryDirectory() as tmp:
            warm = expand([parse_param("controller.K_c=10")], sc, fmu_dir, stop_time=1.0)
            for w in range(workers):  # load the FMUs in every worker first
                warm[0]["run_id"] = f"warm{w}"
                run_sweep(sc, warm, Path(tmp) / f"w{w}", client, fmu_dir, stop_time=1.0)
            res = run_sweep(sc, points, Path(tmp), client, fmu_dir)
        assert res.failed == 0, "a run failed"
        return res.runs_per_s
    finally:
        client.close()
        client.cluster.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=24)
    ap.add_argument("--fmu-dir", default="fmus")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    fmu_dir = Path(args.fmu_dir).resolve()
    build_all(fmu_dir, only_stale=True)
    r1 = rate(1, args.runs, fmu_dir)
    r2 = rate(2, args.runs, fmu_dir)
    result = {
        "runs": args.runs,
        "scenario": "default, 60 s (3000 macro steps)",
        "runs_per_s_1_worker": round(r1, 2),
        "runs_per_s_2_workers": round(r2, 2),
        "runs_per_s_per_core": round(r2 / 2, 2),
        "scaling_efficiency": round(r2 / (2 * r1), 3),
        "cpus": os.cpu_count(),
    }
    emit(result, args.json)


if __name__ == "__main__":
    main()
