"""Benchmark: runs/s of the default 60 s scenario (K_c list) on a local Dask cluster of 1
and 2 worker processes, and on a cluster started the Dask way in the same run
(``dask scheduler`` + 2 ``dask worker`` processes in private mount namespaces, FMUs sent
through Dask, as on other machines); the scheduler's per-task overhead (no-op tasks, and
the scheduler's CPU time per task of the sweep); the client's CPU time per run, with and
without ``--trajectories``.

Usage: python bench/sweep.py [--runs 48] [--noop 2000] [--json]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from _cluster import DaskCluster
from _common import emit

from glider_cosim.build import build_all
from glider_cosim.scenario import load_scenario
from glider_cosim.sweep import expand, make_client, parse_param, run_sweep


def _noop(i: int) -> int:
    return i


def rate(client, workers: int, runs: int, fmu_dir: Path, trajectories: bool = False,
         scheduler_cpu=lambda: 0.0) -> dict:  # fmt: skip
    """Timed sweep of ``runs`` 60 s runs after a warm-up that loads the FMUs everywhere;
    ``scheduler_cpu()``: the scheduler's CPU time, s (measured around the timed sweep)."""
    sc = load_scenario(None)
    points = expand([parse_param(f"controller.K_c=8:40:{runs}")], sc, fmu_dir)
    client.wait_for_workers(workers, timeout=60)
    with tempfile.TemporaryDirectory() as tmp:
        warm = expand([parse_param(f"controller.K_c=9:11:{4 * workers}")], sc, fmu_dir,
                      stop_time=1.0)  # fmt: skip
        run_sweep(sc, warm, Path(tmp) / "warm", client, fmu_dir, stop_time=1.0, chunk=1)
        cpu0, s0 = time.process_time(), scheduler_cpu()
        res = run_sweep(sc, points, Path(tmp) / "timed", client, fmu_dir,
                        trajectories=trajectories)  # fmt: skip
        cpu, sched = time.process_time() - cpu0, scheduler_cpu() - s0
        if res.failed or res.done != runs:
            raise RuntimeError(f"{res.failed} of {runs} runs failed, see {res.path}: "
                               + res.path.read_text()[:1000])  # fmt: skip
    tasks = -(-runs // min(4, -(-runs // (2 * workers))))  # as run_sweep chunks them
    return {"runs_per_s": res.runs_per_s, "client_cpu_ms_per_run": 1e3 * cpu / runs,
            "scheduler_cpu_ms_per_task": 1e3 * sched / tasks}  # fmt: skip


def local(workers: int, runs: int, fmu_dir: Path) -> float:
    client = make_client(workers)
    try:
        return rate(client, workers, runs, fmu_dir)["runs_per_s"]
    finally:
        client.close()
        client.cluster.close()


def external(runs: int, noop: int, fmu_dir: Path) -> dict:
    """Two ``dask worker`` processes that cannot see ``fmu_dir`` (namespaced if root)."""
    from distributed import Client, wait

    with DaskCluster(2, hidden=[fmu_dir]) as cluster, Client(cluster.address) as client:
        cpu = lambda: cluster.cpu_seconds(cluster.scheduler.pid)  # noqa: E731
        r = rate(client, 2, runs, fmu_dir, scheduler_cpu=cpu)
        traj = rate(client, 2, runs, fmu_dir, trajectories=True)
        s0 = cluster.cpu_seconds(cluster.scheduler.pid)
        t0 = time.perf_counter()
        wait(client.map(_noop, range(noop), pure=False))
        wall = time.perf_counter() - t0
        noop_sched = cluster.cpu_seconds(cluster.scheduler.pid) - s0
    return {
        "namespaced": cluster.namespaced,
        "runs_per_s": r["runs_per_s"],
        "client_cpu_ms_per_run": r["client_cpu_ms_per_run"],
        "runs_per_s_trajectories": traj["runs_per_s"],
        "client_cpu_ms_per_run_trajectories": traj["client_cpu_ms_per_run"],
        "sweep_scheduler_cpu_ms_per_task": r["scheduler_cpu_ms_per_task"],
        "noop_tasks_per_s": noop / wall,
        "noop_scheduler_cpu_ms_per_task": 1e3 * noop_sched / noop,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=48)
    ap.add_argument("--noop", type=int, default=2000, help="no-op tasks for the overhead")
    ap.add_argument("--fmu-dir", default="fmus")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    fmu_dir = Path(args.fmu_dir).resolve()
    build_all(fmu_dir, only_stale=True)
    r1 = local(1, args.runs, fmu_dir)
    r2 = local(2, args.runs, fmu_dir)
    ext = external(args.runs, args.noop, fmu_dir)
    result = {
        "runs": args.runs,
        "scenario": "default, 60 s (3000 macro steps)",
        "runs_per_s_1_worker": round(r1, 2),
        "runs_per_s_2_workers": round(r2, 2),
        "runs_per_s_per_core": round(r2 / 2, 2),
        "scaling_efficiency": round(r2 / (2 * r1), 3),
        "external_namespaced_workers": ext["namespaced"],
        "runs_per_s_external_2_workers": round(ext["runs_per_s"], 2),
        "external_vs_local": round(ext["runs_per_s"] / r2, 3),
        "runs_per_s_external_trajectories": round(ext["runs_per_s_trajectories"], 2),
        "client_cpu_ms_per_run": round(ext["client_cpu_ms_per_run"], 2),
        "client_cpu_ms_per_run_trajectories": round(ext["client_cpu_ms_per_run_trajectories"], 2),
        "scheduler_cpu_ms_per_sweep_task": round(ext["sweep_scheduler_cpu_ms_per_task"], 3),
        "noop_tasks_per_s": round(ext["noop_tasks_per_s"], 1),
        "scheduler_cpu_ms_per_noop_task": round(ext["noop_scheduler_cpu_ms_per_task"], 3),
        "cpus": os.cpu_count(),
        "load_avg_1min": round(os.getloadavg()[0], 2),
    }
    emit(result, args.json)


if __name__ == "__main__":
    main()
