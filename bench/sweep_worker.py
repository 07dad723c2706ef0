"""Benchmark: where a sweep worker's CPU goes per run, without Dask.

``glider_cosim.sweeps.worker.run_many`` of ``--runs`` points of the default 60 s
scenario (``controller.K_c`` from 8 to 40, the points ``bench/sweep.py`` runs) in this
process, after a warm-up that loads the FMUs:

- ``worker_cpu_ms_per_run``: CPU time (``time.process_time``) per run, the best of
  ``--repeat`` sweeps;
- ``profile_ms_per_run``: the same sweep once more under cProfile, per run, by part:
  ``loop`` (``FastLoop.run``: the steps in C), ``reset`` (``CoSimulation.reset``: the
  run's parameters and the initialisation), ``metrics`` (``compute_metrics``),
  ``estimation_rms`` (``wrapped_rms``), ``total`` (``run_many``; cProfile's own cost
  inflates it), and ``other`` (the rest: the result row, the recorder);
- ``metrics_ms``: ``compute_metrics`` of one run's table (the columns a sweep records),
  CPU time per call, the best of 5 rounds of 200 calls; ``metrics_ms_limit_cycle`` the
  same for the ``fig3-4-kc`` scenario (a limit cycle: the outcome needs a fit).

Usage: python bench/sweep_worker.py [--runs 240] [--repeat 3] [--flavor native|python]
       [--fmu-dir DIR] [--json]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time
from pathlib import Path

from _common import emit

from glider_cosim.fmus.folders import FLAVORS, prepare_fmus
from glider_cosim.master.cosimulation import CoSimulation
from glider_cosim.runner.metrics import compute_metrics
from glider_cosim.runner.recorders import ArrayRecorder
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for
from glider_cosim.sweeps.sweep import expand, parse_param
from glider_cosim.sweeps.worker import METRIC_COLUMNS, run_many

#: the profiled parts: (file name ending, function name)
PARTS = {
    "loop": ("master/fastloop.py", "run"),
    "reset": ("master/cosimulation.py", "reset"),
    "metrics": ("runner/metrics.py", "compute_metrics"),
    "estimation_rms": ("runner/metrics.py", "wrapped_rms"),
    "total": ("sweeps/worker.py", "run_many"),
}


def metrics_ms(scenario, fmu_dir: Path) -> float:
    """CPU ms of ``compute_metrics`` of one default run's table (best of 5 x 200)."""
    system = system_for(scenario, fmu_dir, scenario.step)
    system.record = [c for c in METRIC_COLUMNS if scenario.observer or "observer" not in c]
    sim = CoSimulation(system, step=scenario.step, coupling=scenario.coupling)
    rec = ArrayRecorder()
    sim.run(scenario.stop_time, rec)
    sim.close()
    data = rec.table() if hasattr(rec, "table") else rec.array()  # before issue 48: array
    best = float("inf")
    for _ in range(5):
        t = time.process_time()
        for _ in range(200):
            compute_metrics(rec.columns, data, scenario, sim)
        best = min(best, (time.process_time() - t) / 200 * 1e3)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=240, help="points of the sweep")
    ap.add_argument("--repeat", type=int, default=3, help="timed sweeps (best)")
    ap.add_argument("--flavor", choices=FLAVORS, default="native", help="which FMUs")
    ap.add_argument("--fmu-dir", default=None, help="FMU folder (default: the per-user cache)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    fmu_dir = prepare_fmus(args.fmu_dir, args.flavor).resolve()
    scenario = load_scenario(None)
    runs = expand([parse_param(f"controller.K_c=8:40:{args.runs}")], scenario, fmu_dir)
    fmus = {k: str(v) for k, v in system_for(scenario, Path(fmu_dir)).fmus.items()}
    run_many(scenario, runs[:4], fmus)  # the FMUs loaded
    cpu = []
    for _ in range(args.repeat):
        t = time.process_time()
        rows = run_many(scenario, runs, fmus)
        cpu.append((time.process_time() - t) / len(runs) * 1e3)
    profile = cProfile.Profile()
    profile.enable()
    run_many(scenario, runs, fmus)
    profile.disable()
    stats = pstats.Stats(profile).stats  # (file, line, name) -> (cc, nc, tt, ct, callers)
    parts = {}
    for part, (file, name) in PARTS.items():
        seconds = sum(v[3] for (f, _, n), v in stats.items() if n == name and f.endswith(file))
        parts[part] = round(seconds / len(runs) * 1e3, 4)
    parts["other"] = round(parts["total"] - sum(v for k, v in parts.items() if k != "total"), 4)
    emit({
        "runs": len(runs), "flavor": args.flavor,
        "worker_cpu_ms_per_run": round(min(cpu), 4),
        "worker_cpu_ms_per_run_all": [round(c, 4) for c in cpu],
        "profile_ms_per_run": parts,
        "metrics_ms": round(metrics_ms(scenario, Path(fmu_dir)), 4),
        "metrics_ms_limit_cycle": round(metrics_ms(load_scenario("fig3-4-kc"), Path(fmu_dir)), 4),
        "outcomes": sorted({str(r.get("outcome")) for r in rows}),
    }, args.json)  # fmt: skip


if __name__ == "__main__":
    main()
