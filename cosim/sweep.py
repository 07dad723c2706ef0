"""Parameter sweeps and Monte Carlo runs on Dask (``glider-cosim sweep``).

Parameter specs (``--param INSTANCE.NAME=SPEC``, repeatable):

- ``6,8,10,15``: a list of values (numbers or ``"X deg"``);
- ``0.5:2.5:5``: ``num`` values from ``start`` to ``stop`` inclusive (linspace);
- ``uniform(-20%,+20%)`` or ``uniform(LOW,HIGH)``: uniform random draws, relative to the
  nominal value (the scenario's, else the FMU's default) or absolute;
- ``normal(20%)`` or ``normal(SD)``: normal random draws around the nominal value.

Lists and ranges form a full grid; random specs are drawn ``--samples`` times per grid
point (numpy Generator seeded by ``--rng-seed``); ``--seeds N`` repeats every run with
sensor-noise seeds 0..N-1 (``plant.noise_seed``). Every run has an id derived from its
parameters and seed, so an interrupted sweep resumes where it stopped.

Each Dask worker keeps one co-simulation per scenario and resets it between runs
(pythonfmu's reset restores the defaults, so every run sets its full parameter set); an
instance that failed is discarded and replaced. A failed run is recorded with its status
and message; tasks of a worker that dies are retried elsewhere by Dask.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import copy
import csv
import hashlib
import io
import itertools
import json
import math
import os
import re
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .master import CoSimulation, FMUCallError, FMUStopped, MasterError
from .metrics import compute_metrics
from .runner import FMU_NAMES, ArrayRecorder, system_for
from .scenario import INSTANCES, Scenario, ScenarioError, load_scenario
from .sweep_cluster import (
    DIST,
    FmuBlob,
    SweepClusterError,
    check_workers,
    local_fmu,
    make_client,
    package_version,
    scatter_fmus,
)
from .sweep_store import SweepStore

METRIC_KEYS = (
    "settling_time_s", "rise_time_s", "overshoot_rad", "overshoot_pct", "control_effort",
    "max_abs_delta_cmd_rad", "final_error_rad", "estimation_rms_rad", "end_time_s",
)  # fmt: skip
METRIC_COLUMNS = ("plant.theta_g", "observer.theta_g_hat", "controller.delta_cmd")
_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_PCT = rf"({_NUM})(%?)"


class SweepSpecError(ValueError):
    """A ``--param`` spec or sweep option is malformed (the message names it)."""


@dataclass(frozen=True)
class ParamSpec:
    """One swept parameter: a fixed list of values, or a random distribution."""

    target: str  # instance.name
    values: tuple[float, ...] = ()
    dist: str = ""  # "uniform" | "normal"
    args: tuple[tuple[float, bool], ...] = ()  # (value, is_percent)

    @property
    def random(self) -> bool:
        return bool(self.dist)

    def draw(self, nominal: float, rng: np.random.Generator) -> float:
        def val(a: tuple[float, bool]) -> float:
            x, pct = a
            return nominal * (1 + x / 100) if pct else x

        if self.dist == "uniform":
            return float(rng.uniform(val(self.args[0]), val(self.args[1])))
        sd = abs(nominal) * self.args[0][0] / 100 if self.args[0][1] else self.args[0][0]
        return float(rng.normal(nominal, sd))


def _value(text: str, where: str) -> float:
    text = text.strip()
    m = re.fullmatch(rf"({_NUM})\s*deg", text)
    if m:
        return math.radians(float(m.group(1)))
    try:
        return float(text)
    except ValueError:
        raise SweepSpecError(f"{where}: {text!r} is not a number (or 'X deg')") from None


def parse_param(item: str) -> ParamSpec:
    """Parse ``INSTANCE.NAME=SPEC`` (grammar in the module docstring)."""
    where = f"--param {item!r}"
    target, sep, spec = item.partition("=")
    inst, dot, name = target.strip().partition(".")
    if not sep or not dot or inst not in INSTANCES or not name:
        raise SweepSpecError(
            f"{where}: expected INSTANCE.NAME=SPEC with INSTANCE one of {', '.join(INSTANCES)}"
        )
    spec = spec.strip()
    target = f"{inst}.{name}"
    m = re.fullmatch(r"(uniform|normal)\(\s*(.*?)\s*\)", spec)
    if m:
        parts = [p.strip() for p in m.group(2).split(",")]
        want = 2 if m.group(1) == "uniform" else 1
        if len(parts) != want:
            raise SweepSpecError(
                f"{where}: {m.group(1)} takes {want} argument(s), e.g. "
                + ("uniform(-20%,+20%)" if want == 2 else "normal(20%)")
            )
        args = []
        for p in parts:
            pm = re.fullmatch(_PCT, p)
            if not pm:
                raise SweepSpecError(f"{where}: {p!r} is not a number or a percentage")
            args.append((float(pm.group(1)), pm.group(2) == "%"))
        if m.group(1) == "normal" and args[0][0] < 0:
            raise SweepSpecError(f"{where}: the standard deviation must be >= 0")
        return ParamSpec(target, dist=m.group(1), args=tuple(args))
    if ":" in spec:
        parts = spec.split(":")
        if len(parts) != 3:
            raise SweepSpecError(f"{where}: a range is START:STOP:NUM, e.g. 2:20:10")
        start, stop = _value(parts[0], where), _value(parts[1], where)
        try:
            num = int(parts[2])
        except ValueError:
            raise SweepSpecError(f"{where}: NUM {parts[2]!r} must be a whole number") from None
        if num < 1:
            raise SweepSpecError(f"{where}: NUM must be >= 1")
        return ParamSpec(target, values=tuple(float(v) for v in np.linspace(start, stop, num)))
    values = tuple(_value(v, where) for v in spec.split(",") if v.strip())
    if not values:
        raise SweepSpecError(f"{where}: no values")
    return ParamSpec(target, values=values)


def run_id(params: dict[str, float], seed: int | None, scenario: Scenario, stop: float) -> str:
    """Deterministic id of a run (resume key)."""
    key = json.dumps([scenario.name, scenario.source, stop, seed, sorted(params.items())])
    return hashlib.sha1(key.encode()).hexdigest()[:16]


def check_targets(scenario: Scenario, fmu_dir: Path, targets: Iterable[str]) -> None:
    """Check that every swept ``instance.name`` is a parameter or input of its FMU.

    The model descriptions of the scenario's FMUs (``fmu_dir`` unless swapped) are the
    source, as for ``run --set``; raises :class:`SweepSpecError` naming the first
    target that is not there, before any work is sent.
    """
    from fmpy import read_model_description

    fmus = system_for(scenario, fmu_dir).fmus
    variables: dict[str, dict[str, str]] = {}
    models: dict[str, str] = {}
    for t in targets:
        inst, _, name = t.partition(".")
        if inst not in fmus:
            raise SweepSpecError(
                f"--param {t}: the scenario {scenario.name} has no instance '{inst}' "
                f"(instances: {', '.join(fmus)})"
            )
        if inst not in variables:
            try:
                md = read_model_description(str(fmus[inst]))
            except Exception as err:  # noqa: BLE001 - fmpy raises plain Exception
                raise SweepSpecError(f"instance {inst}: {fmus[inst]} is not a readable FMU "
                                     f"({err})") from None  # fmt: skip
            variables[inst] = {v.name: v.causality for v in md.modelVariables}
            models[inst] = md.modelName
        causality = variables[inst].get(name)
        if causality is None:
            raise SweepSpecError(
                f"--param {t}: instance {inst} ({models[inst]}) has no variable '{name}'"
            )
        if causality not in ("parameter", "input"):
            raise SweepSpecError(f"--param {t}: {t} has causality {causality}: expected one of "
                                 "parameter, input")  # fmt: skip


def nominal_values(scenario: Scenario, fmu_dir: Path, targets: Iterable[str]) -> dict[str, float]:
    """Nominal value of each target: the scenario's, else the FMU's default."""
    from .monolithic import fmu_parameter_defaults

    fmus = system_for(scenario, fmu_dir).fmus
    defaults = {}
    out = {}
    for t in targets:
        inst, _, name = t.partition(".")
        if name in scenario.parameters.get(inst, {}):
            out[t] = float(scenario.parameters[inst][name])
            continue
        if inst not in defaults:
            defaults[inst] = fmu_parameter_defaults(fmus[inst])
        if name not in defaults[inst]:
            raise SweepSpecError(f"--param {t}: {FMU_NAMES[inst]} has no parameter '{name}'")
        out[t] = float(defaults[inst][name])
    return out


def expand(
    specs: Sequence[ParamSpec],
    scenario: Scenario,
    fmu_dir: Path,
    samples: int = 10,
    seeds: Sequence[int] | None = None,
    rng_seed: int = 0,
    stop_time: float | None = None,
) -> list[dict[str, Any]]:
    """The list of runs: ``{"run_id", "params", "seed"}``."""
    grid = [s for s in specs if not s.random]
    rand = [s for s in specs if s.random]
    nominal = nominal_values(scenario, fmu_dir, [s.target for s in rand])
    rng = np.random.default_rng(rng_seed)
    stop = stop_time or scenario.stop_time
    runs = []
    for combo in itertools.product(*(s.values for s in grid)):
        base = {s.target: v for s, v in zip(grid, combo, strict=True)}
        for _ in range(samples if rand else 1):
            params = dict(base)
            params.update({s.target: s.draw(nominal[s.target], rng) for s in rand})
            for seed in seeds if seeds is not None else [None]:
                runs.append({"run_id": run_id(params, seed, scenario, stop), "params": params,
                             "seed": seed})  # fmt: skip
    return runs


# ----------------------------------------------------------------- worker side
_SIMS: dict[tuple, CoSimulation] = {}
_WORKER_EXIT_SET = False


def _leave_worker_quietly() -> None:
    """In a Dask worker process: at exit, free the cached instances, then leave with
    ``os._exit(0)``. Worker processes ran FMUs many times and were seen to abort in native
    exit handlers ("corrupted double-linked list") after the cluster closed; their exit
    status is not used, and nothing of the sweep is lost (rows are written by the client)."""
    global _WORKER_EXIT_SET
    if _WORKER_EXIT_SET:
        return
    _WORKER_EXIT_SET = True
    try:
        from distributed import get_worker

        get_worker()
    except (ImportError, ValueError):
        return  # not in a Dask worker

    def leave() -> None:
        for sim in list(_SIMS.values()):
            with contextlib.suppress(Exception):
                sim.close()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)

    atexit.register(leave)


def _full_parameters(scenario: Scenario, run: dict[str, Any]) -> dict[str, dict[str, Any]]:
    params = {k: dict(v) for k, v in scenario.parameters.items()}
    for target, value in run["params"].items():
        inst, _, name = target.partition(".")
        params.setdefault(inst, {})[name] = int(value) if name in ("law", "noise_seed") else value
    if run["seed"] is not None:
        params.setdefault("plant", {})["noise_seed"] = int(run["seed"])
    return params


def _csv_text(columns: Sequence[str], data: np.ndarray) -> bytes:
    """A trajectory as the CSV bytes ``run`` writes (17 significant digits)."""
    buf = io.StringIO()
    buf.write(",".join(columns) + "\n")
    if len(data):
        np.savetxt(buf, data, fmt="%.17g", delimiter=",")
    return buf.getvalue().encode()


def run_one(
    scenario: Scenario, run: dict[str, Any], fmus: Mapping[str, FmuBlob | str | Path],
    stop_time: float | None = None, trajectories: bool = False,
) -> dict[str, Any]:  # fmt: skip
    """Run one sweep point in this process, reusing a cached co-simulation.

    Parameters
    ----------
    scenario : Scenario
    run : dict
        ``{"run_id", "params", "seed"}`` (see :func:`expand`).
    fmus : mapping
        Instance -> FMU: an :class:`FmuBlob` (written once into this worker's cache) or a
        path of this process.
    stop_time : float, optional
        Stop time, s (default the scenario's).
    trajectories : bool
        Record every output and return the trajectory as CSV bytes under
        ``"trajectory"`` (written by the client).

    Returns
    -------
    dict
        The result row (parameters, seed, status, message, metrics).
    """
    _leave_worker_quietly()
    local = {inst: local_fmu(f) for inst, f in fmus.items()}
    key = (tuple(sorted((i, str(p)) for i, p in local.items())), scenario.source, scenario.name,
           scenario.feedback, scenario.observer, bool(trajectories))  # fmt: skip
    params = _full_parameters(scenario, run)
    stop = stop_time or scenario.stop_time
    row: dict[str, Any] = {"run_id": run["run_id"], "seed": run["seed"], **run["params"]}
    rec = ArrayRecorder()
    sim = _SIMS.pop(key, None)
    status, message = "ok", ""
    try:
        if sim is None:
            here = copy.copy(scenario)
            here.fmus = {inst: str(p) for inst, p in local.items()}
            system = system_for(here, Path("."))
            if not trajectories:  # only what the metrics need
                system.record = [
                    c for c in METRIC_COLUMNS if scenario.observer or "observer" not in c
                ]
            sim = CoSimulation(system, step=scenario.step, coupling=scenario.coupling)
            sim.system.parameters = params
            sim.initialize()
        else:
            sim.reset(params, replace=True)  # the previous run's values must not linger
        n = round(stop / sim.step_size)
        rec.start(sim.columns)
        rec.row(sim.communication_point())
        for _ in range(n):
            sim.do_step()
            rec.row(sim.communication_point())
    except FMUStopped as err:
        status, message = "stopped", str(err)
    except (FMUCallError, MasterError, ValueError) as err:
        status, message = "error", str(err)
    if sim is not None and status == "ok":
        _SIMS[key] = sim  # reuse: reset next time
    elif sim is not None:
        sim.close()  # frees what is not fatal; a fatal instance is never called again
    cols, data = rec.columns, rec.array() if rec.rows else None
    row.update(status=status, message=message)
    if data is not None and len(data) and sim is not None:
        m = compute_metrics(cols, data, scenario, sim)
        if "observer.theta_g_hat" in cols:
            err = data[:, cols.index("observer.theta_g_hat")] - data[:, cols.index("plant.theta_g")]
            m["estimation_rms_rad"] = float(np.sqrt(np.mean(err**2)))
        row.update({k: m.get(k) for k in METRIC_KEYS})
    if trajectories and cols:  # recording started: the rows up to a failure too
        row["trajectory"] = _csv_text(cols, data if data is not None else np.empty((0, 0)))
    return row


def run_many(
    scenario: Scenario, runs: Sequence[dict[str, Any]], fmus: Mapping[str, FmuBlob | str | Path],
    stop_time: float | None = None, trajectories: bool = False, version: str | None = None,
) -> list[dict[str, Any]]:  # fmt: skip
    """Several sweep points in one task (amortises the scheduling overhead).

    ``version``: the client's glider-cosim version; a worker with another one (one that
    joined after the check at connect) refuses the task with :class:`SweepClusterError`.
    """
    if version is not None and (mine := package_version()) != version:
        raise SweepClusterError(
            f"worker {_worker_address()} has {DIST} {mine}, the client {DIST} {version}"
        )
    return [run_one(scenario, r, fmus, stop_time, trajectories) for r in runs]


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"process {os.getpid()}"


# ----------------------------------------------------------------- client side
@dataclass
class SweepResult:
    """Summary of a sweep: counts and the results file.

    ``failed`` counts the runs that failed in this call, ``failed_total`` every run of
    the sweep recorded as failed in the file (earlier calls included: the exit code).
    """

    total: int
    done: int
    skipped: int
    failed: int
    seconds: float
    path: Path
    failed_total: int = 0

    @property
    def runs_per_s(self) -> float:
        return self.done / self.seconds if self.seconds > 0 else 0.0


def _write_atomically(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


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
    chunk: int = 4,
) -> SweepResult:
    """Run ``runs`` on a Dask ``client`` in tasks of up to ``chunk`` runs; append one row
    per finished run to ``out/sweep.csv`` (resuming: runs already there are skipped,
    runs with the same id are run once; see :mod:`glider_cosim.sweep_store`)."""
    from distributed import as_completed

    out.mkdir(parents=True, exist_ok=True)
    unique = list({r["run_id"]: r for r in runs}.values())
    ids = [r["run_id"] for r in unique]
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
        size = max(1, min(chunk, math.ceil(len(todo) / (2 * n_workers))))
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
                    _write_atomically(traj / f"{row['run_id']}.csv", text)
                store.add(row)
                done += 1
                failed += row.get("status") != "ok"
            store.flush()
            if progress:
                progress(done, len(todo), failed, time.perf_counter() - t0)
        failed_total = store.failed(ids)
    return SweepResult(len(unique), done, len(unique) - len(todo), failed,
                       time.perf_counter() - t0, store.path, failed_total)  # fmt: skip


def write_plots(path: Path, out: Path) -> list[Path]:
    """Plots that apply to the swept parameters (PNG beside the results)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return []

    def num(r: dict, k: str) -> float:
        try:
            return float(r[k])
        except (KeyError, TypeError, ValueError):
            return math.nan

    params = [k for k in rows[0] if "." in k]
    files = []
    if "controller.K_c" in params:
        ok = [r for r in rows if r["status"] == "ok" and r["settling_time_s"] not in ("", None)]
        fig, ax = plt.subplots(figsize=(6, 4))
        sc = ax.scatter([num(r, "control_effort") for r in ok],
                        [num(r, "settling_time_s") for r in ok],
                        c=[num(r, "controller.K_c") for r in ok], cmap="viridis")  # fmt: skip
        fig.colorbar(sc, label="K_c")
        ax.set(xlabel="control effort [rad s]", ylabel="settling time [s]",
               title="Settling time against control effort (Sec. 3.3 trade-off)")  # fmt: skip
        ax.grid(alpha=0.3)
        fig.tight_layout()
        files.append(out / "settling_vs_effort.png")
        fig.savefig(files[-1], dpi=100)
        plt.close(fig)
    if len(params) >= 2:
        a, b = params[:2]
        good = [r["status"] == "ok" and r["settling_time_s"] not in ("", None) for r in rows]
        fig, ax = plt.subplots(figsize=(6, 4))
        for flag, colour, label in ((True, "tab:green", "settles"),
                                    (False, "tab:red", "does not settle / fails")):  # fmt: skip
            pts = [(num(r, a), num(r, b)) for r, g in zip(rows, good, strict=True) if g == flag]
            if pts:
                ax.scatter(*zip(*pts, strict=True), c=colour, label=label, s=18)
        ax.set(xlabel=a, ylabel=b, title="Stability boundary")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        files.append(out / "stability_boundary.png")
        fig.savefig(files[-1], dpi=100)
        plt.close(fig)
    if "plant.noise_std" in params:
        pts = [(num(r, "plant.noise_std"), num(r, "estimation_rms_rad")) for r in rows]
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.scatter(*zip(*pts, strict=True), s=18)
        ax.set(xlabel="sensor noise std [rad]", ylabel="estimation error RMS [rad]",
               title="Estimation error against sensor noise")  # fmt: skip
        ax.grid(alpha=0.3)
        fig.tight_layout()
        files.append(out / "estimation_vs_noise.png")
        fig.savefig(files[-1], dpi=100)
        plt.close(fig)
    return files


def add_parser(sub: Any) -> None:
    """Add the ``sweep`` sub-command to the CLI's sub-parsers."""
    s = sub.add_parser("sweep", help="parameter sweep / Monte Carlo on Dask",
                       description=__doc__.split("\n\n")[1])  # fmt: skip
    s.add_argument("scenario", nargs="?", default=None, help="scenario (default: default)")
    s.add_argument("--param", action="append", default=[], metavar="INSTANCE.NAME=SPEC",
                   help="swept parameter (repeatable): 6,8,10 | 2:20:10 | uniform(-20%%,+20%%)"
                   " | normal(20%%)")  # fmt: skip
    s.add_argument("--samples", type=int, default=10, help="draws for random specs")
    s.add_argument("--seeds", type=int, default=None, help="noise seeds 0..N-1 per run")
    s.add_argument("--rng-seed", type=int, default=0, help="seed of the random draws")
    s.add_argument("--workers", type=int, default=2, help="local worker processes")
    s.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    s.add_argument("--out", default="out/sweep", help="results folder")
    s.add_argument("--format", choices=("csv", "parquet"), default="csv")
    s.add_argument("--trajectories", action="store_true", help="keep each run's results CSV")
    s.add_argument("--stop-time", type=float, default=None, help="stop time, s")
    s.add_argument("--fmu-dir", default="fmus", help="FMU folder (built if missing or stale)")
    s.add_argument("--restart", action="store_true", help="ignore results already in --out")
    s.add_argument("--no-plots", action="store_true")
    s.add_argument("--dashboard", action="store_true", help="serve and print the Dask dashboard")


def main(args: argparse.Namespace) -> int:
    """Run the ``sweep`` sub-command; 0 all ok, 1 some run of the sweep failed (in this
    call or an earlier one recorded in ``sweep.csv``)."""
    from .build import build_all

    if not args.param and args.seeds is None:
        raise SweepSpecError("nothing to sweep: give --param INSTANCE.NAME=SPEC or --seeds N")
    if args.samples < 1 or args.workers < 1 or (args.seeds is not None and args.seeds < 1):
        raise SweepSpecError("--samples, --workers and --seeds must be >= 1")
    if args.stop_time is not None and not args.stop_time > 0:
        raise SweepSpecError(f"--stop-time {args.stop_time}: expected a number > 0")
    if args.format == "parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise SweepSpecError("--format parquet needs pyarrow (pip install pyarrow)") from None
    scenario = load_scenario(args.scenario)
    fmu_dir = Path(args.fmu_dir).resolve()
    build_all(fmu_dir, only_stale=True)
    specs = [parse_param(p) for p in args.param]
    seeds = list(range(args.seeds)) if args.seeds is not None else None
    check_targets(scenario, fmu_dir, [s.target for s in specs] + ["plant.noise_seed"] * bool(seeds))
    runs = expand(specs, scenario, fmu_dir, args.samples, seeds, args.rng_seed, args.stop_time)
    out = Path(args.out)

    def progress(done: int, total: int, failed: int, secs: float) -> None:
        sys.stderr.write(f"\rsweep: {done}/{total} done, {failed} failed, "
                         f"{done / max(secs, 1e-9):.1f} runs/s ")  # fmt: skip
        if done == total:
            sys.stderr.write("\n")
        sys.stderr.flush()

    client = make_client(args.workers, args.scheduler, dashboard=args.dashboard)
    try:
        check_workers(client)
        if args.dashboard:
            print(f"sweep: Dask dashboard at {client.dashboard_link}", flush=True)
        res = run_sweep(scenario, runs, out, client, fmu_dir, stop_time=args.stop_time,
                        trajectories=args.trajectories, restart=args.restart,
                        progress=progress)  # fmt: skip
    finally:
        client.close()
        if not args.scheduler and client.cluster is not None:
            client.cluster.close()
    if args.format == "parquet":
        import pyarrow.csv as pacsv
        import pyarrow.parquet as pq

        pq.write_table(pacsv.read_csv(res.path), out / "sweep.parquet")
    if not args.no_plots:
        write_plots(res.path, out)
    print(f"sweep: {res.total} runs ({res.skipped} already done), {res.done} run now, "
          f"{res.failed} failed, {res.runs_per_s:.2f} runs/s; {res.failed_total} of "
          f"{res.total} failed overall; results in {res.path}")  # fmt: skip
    return 1 if res.failed_total else 0


__all__ = [
    "ScenarioError",
    "SweepSpecError",
    "check_targets",
    "check_workers",
    "make_client",
    "expand",
    "main",
    "parse_param",
    "run_sweep",
]
