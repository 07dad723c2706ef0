"""The worker side of a sweep: the runs of one Dask task, in the worker's process.

Each worker keeps one co-simulation per scenario (and FMU set, and recording) and resets
it between runs: ``fmi2Reset`` of every instance, then every parameter of the run set
again (pythonfmu's reset restores the defaults; the run's full parameter set is given,
so nothing of the previous run lingers), then initialisation. A run that stopped (an
FMU's ``fmi2Discard``: a stall, a diverged estimate) leaves it to be reset too; after an
error (``fmi2Error`` or worse, a refused parameter) it is discarded and replaced: reading
the three FMUs again costs about 3 ms, more than the run. On the native flavor a reset
costs about 0.1 ms (3 instances: reset, setup, 8 parameter sets, initialisation: 20 FMI
calls), against 2.6 ms for the 3000 steps of the default run.

What a task pays once rather than per run: the FMUs' local paths and the cache key
(:func:`run_many`). What a run pays: its parameter set, the reset, the steps (only the
columns the metrics need are recorded unless ``trajectories``), the metrics (numpy:
:mod:`glider_cosim.runner.metrics`, :mod:`glider_cosim.runner.outcome`) and its result
row. The
results are bit for bit those of separate runs (tested, reuse included: A, B, A in one
task).
"""

from __future__ import annotations

import copy
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..master.cosimulation import CoSimulation
from ..master.errors import FMUCallError, FMUStopped, MasterError
from ..runner.metrics import compute_metrics, wrapped_rms
from ..runner.recorders import ArrayRecorder, csv_lines
from ..scenarios.sampling import has_our_observer, with_sampling
from ..scenarios.scenario import Scenario
from ..scenarios.system import system_for
from .cluster import DIST, FmuBlob, SweepClusterError, local_fmu, package_version

if TYPE_CHECKING:
    import numpy as np

#: the metrics of a sweep's row, in ``sweep.csv``'s order
METRIC_KEYS = (
    "settling_time_s", "rise_time_s", "overshoot_rad", "overshoot_pct", "control_effort",
    "max_abs_delta_cmd_rad", "final_error_rad", "estimation_rms_rad", "end_time_s",
    "outcome", "outcome_period_s", "outcome_amplitude_rad", "outcome_rate_per_s", "in_band_s",
)  # fmt: skip
#: the columns a run records for its metrics when no trajectory is kept
METRIC_COLUMNS = ("plant.theta_g", "observer.theta_g_hat", "controller.delta_cmd")

_SIMS: dict[tuple, CoSimulation] = {}


def _full_parameters(scenario: Scenario, run: dict[str, Any]) -> dict[str, dict[str, Any]]:
    params = {k: dict(v) for k, v in scenario.parameters.items()}
    for target, value in run["params"].items():
        inst, _, name = target.partition(".")
        params.setdefault(inst, {})[name] = int(value) if name in ("law", "noise_seed") else value
    if run["seed"] is not None:
        params.setdefault("plant", {})["noise_seed"] = int(run["seed"])
    return with_sampling(params, scenario.step, scenario.source, has_our_observer(scenario))


def _csv_text(columns: Sequence[str], data: np.ndarray | None) -> bytes:
    """A trajectory (None: no rows) as the CSV bytes ``run`` writes (each value as
    ``repr``)."""
    return (",".join(columns) + "\n").encode() + (b"" if data is None else csv_lines(data))


def _local(
    scenario: Scenario, fmus: Mapping[str, FmuBlob | str | Path], trajectories: bool
) -> tuple[dict[str, Path], tuple]:
    """The FMUs as files of this process, and the key of the co-simulation they make."""
    local = {inst: local_fmu(f) for inst, f in fmus.items()}
    key = (tuple(sorted((i, str(p)) for i, p in local.items())), scenario.source, scenario.name,
           scenario.feedback, scenario.observer, bool(trajectories))  # fmt: skip
    return local, key


def run_one(
    scenario: Scenario, run: dict[str, Any], fmus: Mapping[str, FmuBlob | str | Path],
    stop_time: float | None = None, trajectories: bool = False,
) -> dict[str, Any]:  # fmt: skip
    """Run one sweep point in this process, reusing a cached co-simulation.

    Parameters
    ----------
    scenario : Scenario
    run : dict
        ``{"run_id", "params", "seed"}`` (see :func:`~glider_cosim.sweeps.spec.expand`).
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
    local, key = _local(scenario, fmus, trajectories)
    return _run(scenario, run, local, key, stop_time, trajectories)


def _new_sim(scenario: Scenario, local: Mapping[str, Path], trajectories: bool) -> CoSimulation:
    here = copy.copy(scenario)
    here.fmus = {inst: str(p) for inst, p in local.items()}
    system = system_for(here, Path("."))
    if not trajectories:  # only what the metrics need
        system.record = [c for c in METRIC_COLUMNS if scenario.observer or "observer" not in c]
    return CoSimulation(system, step=scenario.step, coupling=scenario.coupling)


def _run(
    scenario: Scenario, run: dict[str, Any], local: Mapping[str, Path], key: tuple,
    stop_time: float | None, trajectories: bool,
) -> dict[str, Any]:  # fmt: skip
    params = _full_parameters(scenario, run)
    stop = stop_time or scenario.stop_time
    row: dict[str, Any] = {"run_id": run["run_id"], "seed": run["seed"], **run["params"]}
    rec = ArrayRecorder()
    sim = _SIMS.pop(key, None)
    status, message = "ok", ""
    try:
        if sim is None:
            sim = _new_sim(scenario, local, trajectories)
            sim.system.parameters = params
            sim.initialize()
        else:
            sim.reset(params, replace=True)  # the previous run's values must not linger
        n = round(stop / sim.step_size)
        rec.start(sim.columns)
        rec.row(sim.communication_point())
        sim.advance(n, rec)
    except FMUStopped as err:
        status, message = "stopped", str(err)
    except (FMUCallError, MasterError, ValueError) as err:
        status, message = "error", str(err)
    if sim is not None and status in ("ok", "stopped"):
        _SIMS[key] = sim  # reuse (a stop is an fmi2Discard, which fmi2Reset clears)
    elif sim is not None:
        sim.close()  # frees what is not fatal; a fatal instance is never called again
    cols, data = rec.columns, rec.array() if len(rec) else None  # numpy: the metrics'
    row.update(status=status, message=message)
    if data is not None and len(data) and sim is not None:
        m = compute_metrics(cols, data, scenario, sim, status)
        if "observer.theta_g_hat" in cols:
            m["estimation_rms_rad"] = wrapped_rms(
                data, cols.index("observer.theta_g_hat"), cols.index("plant.theta_g")
            )
        row.update({k: m.get(k) for k in METRIC_KEYS})
    if trajectories and cols:  # recording started: the rows up to a failure too
        row["trajectory"] = _csv_text(cols, data)
    return row


def run_many(
    scenario: Scenario, runs: Sequence[dict[str, Any]], fmus: Mapping[str, FmuBlob | str | Path],
    stop_time: float | None = None, trajectories: bool = False, version: str | None = None,
) -> list[dict[str, Any]]:  # fmt: skip
    """Several sweep points in one task (amortises the scheduling overhead), each as
    :func:`run_one` runs it; the FMUs' paths and the cache key are found once per task.

    ``version``: the client's glider-cosim version; a worker with another one (one that
    joined after the check at connect) refuses the task with :class:`SweepClusterError`.
    """
    if version is not None and (mine := package_version()) != version:
        raise SweepClusterError(
            f"worker {_worker_address()} has {DIST} {mine}, the client {DIST} {version}"
        )
    if not runs:
        return []
    local, key = _local(scenario, fmus, trajectories)
    return [_run(scenario, r, local, key, stop_time, trajectories) for r in runs]


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"process {os.getpid()}"


__all__ = ["METRIC_COLUMNS", "METRIC_KEYS", "run_many", "run_one"]
