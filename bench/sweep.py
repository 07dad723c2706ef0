"""Benchmark: runs/s of the default 60 s scenario (K_c list) on a local Dask cluster of 1
and 2 worker processes, and on a cluster started the Dask way in the same run
(``dask scheduler`` + 2 ``dask worker`` processes in private mount namespaces, FMUs sent
through Dask, as on other machines); the scheduler's per-task overhead (no-op tasks, and
the scheduler's CPU time per task of the sweep); the client's CPU time per run, with and
without ``--trajectories``. The FMUs are the native flavor's unless ``--flavor python``.

The per-core figures (one round each, medians over the rounds):

- ``runs_per_s_per_core``: runs/s of the local cluster of 1 worker process (one thread;
  the scheduler and the client run in this process, beside it).
- ``in_memory_run_ms``: the in-memory run time of one run, measured in this process in
  the same round: the default scenario (60 s, 3000 macro steps, the bench's flavor) as
  ``simulate(scenario, out=None)`` runs it, ``CoSimulation.run`` into an
  ``ArrayRecorder`` recording every column (instantiation, parameters, initialisation
  and the 3000 steps) and the recorder's array; not timed: reading the FMUs (unzip, model
  description, loading the library, ``CoSimulation.load``), the metrics, freeing. The
  median of ``--repeats`` runs.
- ``sweep_efficiency``: ``runs_per_s_per_core`` times ``in_memory_run_ms`` / 1000 of
  the same round: the share of a core a sweep spends running the loop (1.0: no overhead
  per run or per task; the sweep records 3 columns instead of all, so it can exceed 1).
  Per round in ``sweep_efficiency_per_round``, with ``load_avg_1min_per_round``.
- The same in CPU time, which other work on the machine disturbs less:
  ``in_memory_run_cpu_ms`` (this process's CPU time of the in-memory run),
  ``worker_cpu_ms_per_run_1_worker`` (the worker process's CPU time over the timed sweep,
  per run: its event loop and heartbeats included) and ``sweep_efficiency_cpu``, the
  first over the second.
- ``runs_per_s_1_worker_dask_trim`` and ``worker_cpu_ms_per_run_1_worker_dask_trim``: the
  same 1-worker sweep with the worker started as Dask starts it, with
  ``MALLOC_TRIM_THRESHOLD_=65536`` (glider-cosim's local workers start without it:
  ``glider_cosim.sweeps.cluster.NO_TRIM``), in the same rounds.

Each timed sweep runs ``--runs`` points (default 240, about 0.7 s on one native worker):
a sweep's fixed start (the FMUs sent, the results file, the first task's round trip) is
about 17 ms here, a tenth of a 48-run sweep (the default before) and 2-3 % of this one.

The paths run interleaved for ``--rounds`` rounds (the machine's load drifts); the
scheduler's CPU time is read from /proc: its idle rate (no workers; 2 workers and a client)
is measured and subtracted from the no-op tasks' figure.

``--per-core``: the per-core figures alone (``runs_per_s_per_core``, ``in_memory_run_ms``,
``sweep_efficiency``: the local cluster of 1 worker and the in-memory run), no other
cluster. ``--python PYTHON`` (repeatable): those per-core figures of this script run by
this interpreter and by each ``PYTHON`` (another install of glider-cosim, e.g. main's),
in turn within each of ``--rounds`` rounds (the load drifts), on the same FMU folder;
the medians of each and ``runs_per_s_per_core_ratio`` (each ``PYTHON``'s over this one's
is ``1 / ratio``: this one's over each other's).

Usage: python bench/sweep.py [--runs 240] [--rounds 3] [--noop 2000] [--repeats 20]
       [--flavor native|python] [--fmu-dir DIR] [--per-core] [--python PYTHON] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _cluster import DaskCluster
from _common import emit

from glider_cosim.fmus.folders import FLAVORS, prepare_fmus
from glider_cosim.master.cosimulation import CoSimulation
from glider_cosim.runner.recorders import ArrayRecorder
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for
from glider_cosim.sweeps.sweep import expand, make_client, parse_param, run_sweep, task_size


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
        w0 = client.run(time.process_time)
        cpu0, s0 = time.process_time(), scheduler_cpu()
        res = run_sweep(sc, points, Path(tmp) / "timed", client, fmu_dir,
                        trajectories=trajectories)  # fmt: skip
        cpu, sched = time.process_time() - cpu0, scheduler_cpu() - s0
        w1 = client.run(time.process_time)
        if res.failed or res.done != runs:
            raise RuntimeError(f"{res.failed} of {runs} runs failed, see {res.path}: "
                               + res.path.read_text()[:1000])  # fmt: skip
    tasks = -(-runs // task_size(runs, workers))  # as run_sweep chunks them
    return {"runs_per_s": res.runs_per_s, "client_cpu_ms_per_run": 1e3 * cpu / runs,
            "scheduler_cpu_ms_per_task": 1e3 * sched / tasks, "tasks": tasks,
            "seconds": res.seconds,
            "worker_cpu_ms_per_run": 1e3 * sum(w1[a] - w0[a] for a in w1) / runs}  # fmt: skip


def in_memory_run_s(fmu_dir: Path, repeats: int) -> tuple[float, float]:
    """The in-memory run time of one default run and its CPU time, s (medians of
    ``repeats``; see the module docstring for what is timed)."""
    sc = load_scenario(None)
    times, cpu = [], []
    for _ in range(repeats):
        sim = CoSimulation(system_for(sc, fmu_dir), step=sc.step, coupling=sc.coupling)
        sim.load()  # reading the FMUs: not timed
        rec = ArrayRecorder()
        t0, c0 = time.perf_counter(), time.process_time()
        sim.run(sc.stop_time, rec)
        rec.array()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        sim.close()
    return statistics.median(times), statistics.median(cpu)


def _idle(cpu_seconds, seconds: float = 6.0) -> float:
    """CPU time per second of a process doing nothing but its housekeeping."""
    s0, t0 = cpu_seconds(), time.perf_counter()
    time.sleep(seconds)
    return (cpu_seconds() - s0) / (time.perf_counter() - t0)


def _median(xs: list[float]) -> float:
    return statistics.median(xs)


def per_core(args: argparse.Namespace, fmu_dir: Path) -> dict:
    """The per-core figures (module docstring) of ``args.rounds`` rounds: runs/s of a local
    cluster of 1 worker, the in-memory run time and the sweep's efficiency."""
    rates, run_ms, efficiency, loads = [], [], [], []
    for _ in range(args.rounds):
        local = make_client(1)
        try:
            rates.append(rate(local, 1, args.runs, fmu_dir)["runs_per_s"])
        finally:
            local.close()
            local.cluster.close()
        wall, _ = in_memory_run_s(fmu_dir, args.repeats)
        run_ms.append(1e3 * wall)
        efficiency.append(rates[-1] * wall)
        loads.append(os.getloadavg()[0])
    return {
        "runs": args.runs, "rounds": args.rounds, "flavor": args.flavor,
        "runs_per_s_per_core": round(_median(rates), 2),
        "in_memory_run_ms": round(_median(run_ms), 3),
        "sweep_efficiency": round(_median(efficiency), 3),
        "runs_per_s_1_worker": [round(x, 2) for x in rates],
        "sweep_efficiency_per_round": [round(x, 3) for x in efficiency],
        "load_avg_1min_per_round": [round(x, 2) for x in loads],
    }  # fmt: skip


def compare(args: argparse.Namespace, fmu_dir: Path) -> dict:
    """:func:`per_core` of this interpreter and of each ``--python``, one round of each in
    turn, ``args.rounds`` times; their medians and runs/s per core ratios."""
    pythons = [sys.executable, *args.python]
    rounds: dict[str, list[dict]] = {p: [] for p in pythons}
    for _ in range(args.rounds):
        for py in pythons:
            cmd = [py, __file__, "--per-core", "--rounds", "1", "--runs", str(args.runs),
                   "--repeats", str(args.repeats), "--flavor", args.flavor,
                   "--fmu-dir", str(fmu_dir), "--json"]  # fmt: skip
            done = subprocess.run(cmd, capture_output=True, text=True, check=True)
            rounds[py].append(json.loads(done.stdout.strip().splitlines()[-1]))
    out: dict = {"runs": args.runs, "rounds": args.rounds, "flavor": args.flavor,
                 "fmu_dir": str(fmu_dir)}  # fmt: skip
    for k, py in enumerate(pythons):
        rs = rounds[py]
        out[f"python_{k}"] = py
        for key in ("runs_per_s_per_core", "in_memory_run_ms", "sweep_efficiency"):
            out[f"{key}_{k}"] = round(_median([r[key] for r in rs]), 3)
            out[f"{key}_{k}_per_round"] = [r[key] for r in rs]
        if k:
            out[f"runs_per_s_per_core_ratio_0_over_{k}"] = round(
                out["runs_per_s_per_core_0"] / out[f"runs_per_s_per_core_{k}"], 3
            )
    out["load_avg_1min_per_round"] = [r["load_avg_1min_per_round"][0] for r in rounds[pythons[0]]]
    return out


#: Dask's ``distributed.nanny.pre-spawn-environ`` value of ``MALLOC_TRIM_THRESHOLD_``
DASK_TRIM = "65536"


def main() -> None:
    from distributed import Client, wait

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=240,
                    help="runs of each timed sweep (48, the default before: a 0.15 s sweep, "
                         "its fixed start a third of it)")  # fmt: skip
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds of each path")
    ap.add_argument("--noop", type=int, default=2000, help="no-op tasks for the overhead")
    ap.add_argument("--repeats", type=int, default=20, help="in-memory runs per round")
    ap.add_argument("--flavor", choices=FLAVORS, default="native", help="which FMUs")
    ap.add_argument("--fmu-dir", default=None, help="FMU folder (default: the per-user cache)")
    ap.add_argument(
        "--per-core",
        action="store_true",
        help="the per-core figures alone (1 local worker, the in-memory run)",
    )
    ap.add_argument("--python", action="append", default=[],
                    help="another interpreter whose per-core figures are measured in turn "
                         "(repeatable)")  # fmt: skip
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    # SIGTERM leaves through the context managers, which kill the cluster's processes
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    fmu_dir = prepare_fmus(args.fmu_dir, args.flavor).resolve()
    if args.python:
        emit(compare(args, fmu_dir), args.json)
        return
    if args.per_core:
        emit(per_core(args, fmu_dir), args.json)
        return
    run_ms: list[float] = []
    efficiency: list[float] = []
    run_cpu_ms: list[float] = []
    worker_ms: list[float] = []
    loads: list[float] = []
    rates: dict[str, list[float]] = {"local1": [], "dask_trim": [], "local2": [], "ext": [],
                                     "ext_traj": []}  # fmt: skip
    trim_ms: list[float] = []
    client_ms: dict[str, list[float]] = {"ext": [], "ext_traj": []}
    sched_pct: list[float] = []
    with DaskCluster(0, hidden=[]) as alone:  # the scheduler's own idle load
        idle0 = _idle(lambda: alone.cpu_seconds(alone.scheduler.pid))
    with DaskCluster(2, hidden=[fmu_dir]) as cluster:
        cpu = lambda: cluster.cpu_seconds(cluster.scheduler.pid)  # noqa: E731
        with Client(cluster.address) as ext:
            ext.wait_for_workers(2, timeout=60)
            idle = _idle(cpu)  # with 2 workers and a client: + their heartbeats
        for _ in range(args.rounds):  # interleaved: the machine's load drifts
            # no other client in this process meanwhile: the local clusters' results
            # reached it in bursts, seconds late, while the external one's was connected
            # the local cluster's scheduler runs in this process: started and closed
            # here, so the client's CPU time below is the client's alone; "dask_trim":
            # the workers started with Dask's MALLOC_TRIM_THRESHOLD_ (ours start without)
            for n, name in ((1, "local1"), (1, "dask_trim"), (2, "local2")):
                if name == "dask_trim":
                    os.environ["MALLOC_TRIM_THRESHOLD_"] = DASK_TRIM
                try:
                    local = make_client(n)
                finally:
                    os.environ.pop("MALLOC_TRIM_THRESHOLD_", None)
                try:
                    r = rate(local, n, args.runs, fmu_dir)
                    rates[name].append(r["runs_per_s"])
                finally:
                    local.close()
                    local.cluster.close()
                if name == "dask_trim":
                    trim_ms.append(r["worker_cpu_ms_per_run"])
                if name == "local1":  # the run time of one run, in the same round
                    wall, cpu_s = in_memory_run_s(fmu_dir, args.repeats)
                    run_ms.append(1e3 * wall)
                    run_cpu_ms.append(1e3 * cpu_s)
                    worker_ms.append(r["worker_cpu_ms_per_run"])
                    efficiency.append(rates["local1"][-1] * wall)
                    loads.append(os.getloadavg()[0])
            with Client(cluster.address) as ext:
                r = rate(ext, 2, args.runs, fmu_dir, scheduler_cpu=cpu)
                rates["ext"].append(r["runs_per_s"])
                client_ms["ext"].append(r["client_cpu_ms_per_run"])
                sched_pct.append(r["scheduler_cpu_ms_per_task"] * r["tasks"] / (10 * r["seconds"]))
                r = rate(ext, 2, args.runs, fmu_dir, trajectories=True)
                rates["ext_traj"].append(r["runs_per_s"])
                client_ms["ext_traj"].append(r["client_cpu_ms_per_run"])
        with Client(cluster.address) as ext:
            s0, t0 = cpu(), time.perf_counter()
            wait(ext.map(_noop, range(args.noop), pure=False))
            wall = time.perf_counter() - t0
        noop_ms = 1e3 * (cpu() - s0 - idle * wall) / args.noop
        namespaced = cluster.namespaced
    best = {k: max(v) for k, v in rates.items()}
    result = {
        "runs": args.runs,
        "rounds": args.rounds,
        "scenario": "default, 60 s (3000 macro steps)",
        "flavor": args.flavor,
        "runs_per_s_per_core": round(_median(rates["local1"]), 2),
        "in_memory_run_ms": round(_median(run_ms), 3),
        "sweep_efficiency": round(_median(efficiency), 3),
        "sweep_efficiency_per_round": [round(x, 3) for x in efficiency],
        "in_memory_run_cpu_ms": round(_median(run_cpu_ms), 3),
        "worker_cpu_ms_per_run_1_worker": round(_median(worker_ms), 3),
        "sweep_efficiency_cpu": round(_median(run_cpu_ms) / _median(worker_ms), 3),
        "runs_per_s_1_worker_dask_trim": [round(x, 2) for x in rates["dask_trim"]],
        "worker_cpu_ms_per_run_1_worker_dask_trim": round(_median(trim_ms), 3),
        "load_avg_1min_per_round": [round(x, 2) for x in loads],
        "runs_per_s_1_worker": [round(x, 2) for x in rates["local1"]],
        "runs_per_s_2_workers": [round(x, 2) for x in rates["local2"]],
        "runs_per_s_external_2_workers": [round(x, 2) for x in rates["ext"]],
        "runs_per_s_external_trajectories": [round(x, 2) for x in rates["ext_traj"]],
        "external_namespaced_workers": namespaced,
        "best_scaling_efficiency": round(best["local2"] / (2 * best["local1"]), 3),
        "best_external_vs_local": round(best["ext"] / best["local2"], 3),
        "median_external_vs_local": round(_median(rates["ext"]) / _median(rates["local2"]), 3),
        "client_cpu_ms_per_run": round(_median(client_ms["ext"]), 2),
        "client_cpu_ms_per_run_trajectories": round(_median(client_ms["ext_traj"]), 2),
        "scheduler_idle_cpu_pct_no_workers": round(100 * idle0, 2),
        "scheduler_idle_cpu_pct_2_workers": round(100 * idle, 2),
        "scheduler_cpu_pct_during_sweep": round(_median(sched_pct), 2),
        "noop_tasks_per_s": round(args.noop / wall, 1),
        "scheduler_cpu_ms_per_noop_task": round(noop_ms, 3),
        "cpus": os.cpu_count(),
        "load_avg_1min": round(os.getloadavg()[0], 2),
    }
    emit(result, args.json)


if __name__ == "__main__":
    main()
