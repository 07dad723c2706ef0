"""Parameter sweeps and Monte Carlo runs on Dask (``glider-cosim sweep``).

Parameter specs (``--param INSTANCE.NAME=SPEC``, repeatable):

- ``6,8,10,15``: a list of values (numbers, ``"X deg"`` for an angle, or in the
  variable's declared unit, ``"0.2 m/s"``), each checked like ``run --set`` before any run;
- ``0.5:2.5:5``: ``num`` evenly spaced values from ``start`` to ``stop`` inclusive, each
  the exact decimal rounded to 15 significant digits (``0.1:0.5:5`` is 0.1, 0.2, 0.3,
  0.4, 0.5, as ``sweep.csv`` shows them; :func:`~glider_cosim.sweeps.spec.range_values`);
- ``uniform(-20%,+20%)`` or ``uniform(LOW,HIGH)``: uniform random draws, relative to the
  nominal value (the scenario's, else the FMU's default) or absolute;
- ``normal(20%)`` or ``normal(SD)``: normal random draws around the nominal value.

Lists and ranges form a full grid; random specs are drawn ``--samples`` times per grid
point (numpy Generator seeded by ``--rng-seed``); ``--seeds N`` repeats every run with
sensor-noise seeds 0..N-1 (``plant.noise_seed``). Every run has an id derived from its
parameters and seed, so an interrupted sweep resumes where it stopped.

Each Dask worker keeps one co-simulation per scenario and resets it between runs
(pythonfmu's reset restores the defaults, so every run sets its full parameter set); an
instance that failed is discarded and replaced. Runs go to the workers in tasks of up to
32 runs (4 tasks per worker at least). A failed run is recorded with its status and
message; tasks of a worker that dies are retried elsewhere by Dask.

Modules by purpose: :mod:`.spec` (specs, the list of runs, the up-front name check),
:mod:`.store` (``sweep.csv``, safe to kill), :mod:`.folder` (one sweep per folder:
``sweep.json``), :mod:`.cluster` (clients, version check,
FMUs sent to workers), :mod:`.worker` (the runs of a task, on the worker), :mod:`.plots`;
this module holds the client loop, :func:`sweep`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..inputs.text import command_line
from ..master.errors import Interrupted
from ..scenarios.fields import ScenarioError
from ..scenarios.scenario import Scenario, load_scenario
from ..scenarios.system import swapped, system_for
from .cluster import (
    FmuBlob,
    SweepClusterError,
    check_workers,
    make_client,
    package_version,
    scatter_fmus,
)
from .folder import TABLE_FILE, SweepFolderError, check_folder, recorded_ids, start_folder
from .plots import write_plots
from .spec import (
    ParamSpec,
    SweepSpecError,
    check_ranges_of,
    check_targets,
    expand,
    nominal_values,
    parse_param,
    run_id,
)
from .store import SHOWN_FAILURES, SweepStore, _short, describe_failures, write_atomically
from .worker import METRIC_KEYS, _csv_text, run_many, run_one  # noqa: F401 (re-exported)

#: runs per Dask task at most (:func:`run_sweep`'s ``chunk``): about 0.1 s of native runs
CHUNK = 32


# ----------------------------------------------------------------- client side
@dataclass
class SweepResult:
    """Summary of a sweep: counts and the results file.

    ``failed`` counts the runs that failed in this call, ``failed_total`` every run of
    the sweep recorded as failed in the file (earlier calls included: the exit code);
    ``failures`` holds the first :data:`~glider_cosim.sweeps.store.SHOWN_FAILURES` of
    those rows (parameters, seed, status, message), which the CLI names.
    """

    total: int
    done: int
    skipped: int
    failed: int
    seconds: float
    path: Path
    failed_total: int = 0
    failures: list[dict[str, Any]] = field(default_factory=list)

    @property
    def runs_per_s(self) -> float:
        return self.done / self.seconds if self.seconds > 0 else 0.0


def task_size(runs: int, workers: int, chunk: int = CHUNK) -> int:
    """Runs per task of a sweep of ``runs`` runs on ``workers`` workers: up to ``chunk``
    (a task costs the scheduler, the client and the worker about 1 ms each: 32 native
    runs of 3 ms make it 1 %), fewer so that each worker gets 4 tasks at least (the
    last tasks end together; progress and retries are per task)."""
    return max(1, min(chunk, math.ceil(runs / (4 * max(1, workers)))))


def run_sweep(
    scenario: Scenario,
    runs: Sequence[dict[str, Any]],
    out: Path,
    client: Any,
    fmu_dir: Path,
    *,
    stop_time: float | None = None,
    trajectories: bool = False,
    restart: bool = False,
    progress: Callable[[int, int, int, float], None] | None = None,
    chunk: int = CHUNK,
    spec: str = "",
) -> SweepResult:
    """Run ``runs`` on a Dask ``client`` in tasks of up to ``chunk`` runs; append one row
    per finished run to ``out/sweep.csv`` (resuming: runs already there are skipped,
    runs with the same id are run once; see :mod:`glider_cosim.sweeps.store`).

    A folder that holds another sweep's results is refused (:class:`SweepFolderError`,
    before any run) unless ``restart``; ``spec`` (the sweep as the user wrote it) names
    this sweep in ``sweep.json`` and in that message (:mod:`glider_cosim.sweeps.folder`).
    """
    from distributed import as_completed

    unique = list({r["run_id"]: r for r in runs}.values())
    ids = [r["run_id"] for r in unique]
    start_folder(out, ids, spec, restart)
    param_cols = sorted({k for r in unique for k in r["params"]})
    cols = ["run_id", "seed", *param_cols, "status", "message", *METRIC_KEYS]
    traj = None
    if trajectories:
        traj = out / "trajectories"
        traj.mkdir(exist_ok=True)
        for stale in traj.glob(".*.tmp"):  # left by a kill while writing
            stale.unlink(missing_ok=True)
    t0 = time.perf_counter()
    failed = done = 0
    with SweepStore(out / "sweep.csv", cols, restart=restart) as store:
        done_ids = store.done()
        todo = [r for r in unique if r["run_id"] not in done_ids]
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        size = task_size(len(todo), n_workers, chunk)
        chunks = [todo[i : i + size] for i in range(0, len(todo), size)]
        fmus = scatter_fmus(client, system_for(scenario, Path(fmu_dir)).fmus) if todo else {}
        futures = {
            client.submit(run_many, scenario, c, fmus, stop_time, trajectories,
                          package_version(), pure=False, retries=3): c
            for c in chunks
        }  # fmt: skip
        for fut in as_completed(list(futures)):
            try:
                result = fut.result()
            except Exception as err:  # noqa: BLE001 - a task that failed on every retry
                result = [{"run_id": r["run_id"], "seed": r["seed"], **r["params"],
                           "status": "error", "message": f"task failed: {err}"}
                          for r in futures[fut]]  # fmt: skip
            for row in result:
                text = row.pop("trajectory", None)
                if row["run_id"] in store.rows:
                    continue  # recorded already (a run listed twice)
                if traj is not None and text is not None:
                    write_atomically(traj / f"{row['run_id']}.csv", text)
                store.add(row)
                done += 1
                failed += row.get("status") != "ok"
            store.flush()
            if progress:
                progress(done, len(todo), failed, time.perf_counter() - t0)
        failed_total = store.failed(ids)
        failures = store.failed_rows(ids, SHOWN_FAILURES)
    return SweepResult(len(unique), done, len(unique) - len(todo), failed,
                       time.perf_counter() - t0, store.path, failed_total, failures)  # fmt: skip


def spec_text(
    scenario: str | None,
    param: Sequence[str],
    specs: Sequence[ParamSpec],
    samples: int,
    rng_seed: int,
    seeds: int | None,
    stop_time: float | None,
) -> str:
    """The options that make a sweep's list of runs, as the user wrote them (shell-quoted),
    e.g. ``--param controller.K_c=2:30:15 --stop-time 20``."""
    import shlex

    words = [scenario] if scenario else []
    for item in param:
        words += ["--param", item]
    if any(s.random for s in specs):
        words += ["--samples", str(samples), "--rng-seed", str(rng_seed)]
    if seeds is not None:
        words += ["--seeds", str(seeds)]
    if stop_time is not None:
        words += ["--stop-time", f"{stop_time:g}"]
    return shlex.join(words)


def interrupted(
    err: KeyboardInterrupt, out: Path, ids: Sequence[str], argv: Sequence[str] = ()
) -> Interrupted:
    """``err`` as :class:`Interrupted`, with what the console says is kept: ``37 of 240
    runs in out/sweep/sweep.csv; resume with: glider-cosim sweep ...`` (``argv``, the
    command as given, without ``--restart``)."""
    stop = err if isinstance(err, Interrupted) else Interrupted()
    table = out / TABLE_FILE
    done = len(recorded_ids(table) & set(ids))
    restart = [w for w in argv if len(w) > 3 and "--restart".startswith(w)]  # "--rest" too
    stop.kept = (f"{done} of {len(set(ids))} runs in {table}; resume with: "
                 f"{command_line(list(argv), drop=restart)}")  # fmt: skip
    return stop


#: the runs that did not settle named by the sweep's summary line at most
SHOWN_UNSETTLED = 8


def outcome_summary(path: Path, param_names: Sequence[str], shown: int = SHOWN_UNSETTLED) -> str:
    """The sweep's last line: how many runs of ``sweep.csv`` (``path``) settled, and the
    parameter values (and seed) of those that did not, with their outcome (``error`` and
    such for a run that failed): ``sweep: 13 of 15 runs settled; not settled:
    controller.K_c=2 (limit cycle), controller.K_c=3 (diverged)``; at most ``shown`` of
    them, then how many more."""
    import csv

    from ..runner.outcome import SETTLED

    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    others = []
    for row in rows:
        outcome = row.get("outcome") or ""
        if row.get("status") == "ok" and outcome == SETTLED:
            continue
        what = [f"{k}={_short(row[k])}" for k in param_names if row.get(k, "") != ""]
        if row.get("seed", "") != "":
            what.append(f"seed {row['seed']}")
        why = outcome if row.get("status") == "ok" else (row.get("status") or "failed")
        others.append(f"{' '.join(what) or 'run ' + row.get('run_id', '?')} ({why})")
    line = f"sweep: {len(rows) - len(others)} of {len(rows)} runs settled"
    if others:
        line += "; not settled: " + ", ".join(others[:shown])
        if len(others) > shown:
            line += f" and {len(others) - shown} more (in {path.name})"
    return line


def sweep(
    scenario: str | Path | None = None,
    param: Sequence[str] = (),
    *,
    fmu_dir: str | Path,
    samples: int = 10,
    seeds: int | None = None,
    rng_seed: int = 0,
    workers: int = 2,
    scheduler: str | None = None,
    out: str | Path = "out/sweep",
    format: str = "csv",  # noqa: A002
    trajectories: bool = False,
    stop_time: float | None = None,
    restart: bool = False,
    no_plots: bool = False,
    dashboard: bool = False,
    argv: Sequence[str] = (),
) -> int:
    """Run a parameter sweep or Monte Carlo study on Dask (``glider-cosim sweep``: each
    keyword is the option of the same name).

    Parameters
    ----------
    scenario : path or shipped name, optional
        The scenario swept (default: ``default``).
    param : sequence of str
        ``INSTANCE.NAME=SPEC`` of each swept parameter (the module's docstring).
    fmu_dir : path
        Our FMUs (built there if missing or stale).
    samples : int
        Draws of the random specs per grid point.
    seeds : int, optional
        Repeat each run with sensor-noise seeds ``0..seeds-1``.
    rng_seed : int
        Seed of the random draws.
    workers : int
        Local Dask worker processes (without ``scheduler``).
    scheduler : str, optional
        Address of an existing Dask scheduler.
    out : path
        The sweep's folder (the same sweep resumes there).
    format : {"csv", "parquet"}
        Format of the table (parquet needs pyarrow).
    trajectories : bool
        Keep each run's results CSV.
    stop_time : float, optional
        Stop time of every run, s (default: the scenario's).
    restart : bool
        Replace the results in ``out`` (another sweep's too).
    no_plots : bool
        Skip the PNG plots.
    dashboard : bool
        Serve and print the Dask dashboard.
    argv : sequence of str
        The command line as given, for the "resume with:" line of an interrupted sweep.

    Returns
    -------
    int
        0 if every run succeeded, 1 if one failed (in this call or an earlier one
        recorded in ``sweep.csv``).
    """
    from ..fmus.folders import build_all

    if not param and seeds is None:
        raise SweepSpecError("nothing to sweep: give --param INSTANCE.NAME=SPEC or --seeds N")
    if samples < 1 or workers < 1 or (seeds is not None and seeds < 1):
        raise SweepSpecError("--samples, --workers and --seeds must be >= 1")
    if stop_time is not None and not stop_time > 0:
        raise SweepSpecError(f"--stop-time {stop_time}: expected a number > 0")
    if format == "parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise SweepSpecError("--format parquet needs pyarrow (pip install pyarrow)") from None
    shown = None if scenario is None else str(scenario)
    sc = load_scenario(scenario)
    specs = [parse_param(p) for p in param]
    check_ranges_of(specs, sc)  # units and valid ranges, as run --set: before any run
    fmu_dir = Path(fmu_dir).resolve()
    build_all(fmu_dir, only_stale=True, skip=swapped(sc))
    seed_list = list(range(seeds)) if seeds is not None else None
    check_targets(sc, fmu_dir, ["plant.noise_seed"] * bool(seed_list), specs)
    runs = expand(specs, sc, fmu_dir, samples, seed_list, rng_seed, stop_time)
    out = Path(out)
    spec = spec_text(shown, param, specs, samples, rng_seed, seeds, stop_time)
    check_folder(out, [r["run_id"] for r in runs], spec, restart)  # before Dask starts

    from ..progress import dask_start, say, sweep_progress

    say(f"sweep: {dask_start(workers, scheduler)}")
    try:
        client = make_client(workers, scheduler, dashboard=dashboard)
        try:
            check_workers(client)
            if dashboard:
                print(f"sweep: Dask dashboard at {client.dashboard_link}", flush=True)
            progress, bar = sweep_progress()  # runs done, failed, runs/s
            with bar:
                res = run_sweep(sc, runs, out, client, fmu_dir, stop_time=stop_time,
                                trajectories=trajectories, restart=restart,
                                progress=progress, spec=spec)  # fmt: skip
        finally:
            client.close()
            if not scheduler and client.cluster is not None:
                client.cluster.close()
    except KeyboardInterrupt as err:  # Ctrl-C (SIGTERM: Interrupted): say what is kept
        raise interrupted(err, out, [r["run_id"] for r in runs], argv) from None
    if format == "parquet":
        import pyarrow.csv as pacsv
        import pyarrow.parquet as pq

        pq.write_table(pacsv.read_csv(res.path), out / "sweep.parquet")
    if not no_plots:
        say(f"sweep: drawing the plots into {out}")
        write_plots(res.path, out)
    print(f"sweep: {res.total} runs ({res.skipped} already done), {res.done} run now, "
          f"{res.failed} failed, {res.runs_per_s:.2f} runs/s; {res.failed_total} of "
          f"{res.total} failed overall; results in {res.path}")  # fmt: skip
    for line in describe_failures(res.failures, res.failed_total, res.path,
                                  [s.target for s in specs]):  # fmt: skip
        print(line)
    print(outcome_summary(res.path, [s.target for s in specs]))
    return 1 if res.failed_total else 0


__all__ = [
    "FmuBlob",
    "ParamSpec",
    "ScenarioError",
    "SweepClusterError",
    "SweepFolderError",
    "SweepResult",
    "SweepSpecError",
    "check_targets",
    "check_workers",
    "expand",
    "sweep",
    "make_client",
    "nominal_values",
    "outcome_summary",
    "parse_param",
    "run_id",
    "run_many",
    "run_one",
    "run_sweep",
    "write_plots",
]
