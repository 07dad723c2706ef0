"""Run a scenario on the three glider FMUs: the Python API behind ``glider-cosim run``."""

from __future__ import annotations

import ctypes
import json
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .build import build_all, fmu_folder
from .inputs.check import check_system_values
from .inputs.text import quote
from .master import (
    DEFAULT_MAX_STEPS,
    CoSimulation,
    FMUCallError,
    FMUStopped,
    Interrupted,
    MasterError,
    System,
    SystemSpecError,
    count_steps,
)
from .metrics import compute_metrics
from .provenance import clear_owned, marked_events, run_record
from .scenario import Scenario, has_our_observer, load_scenario, with_sampling

log = logging.getLogger(__name__)

FMU_NAMES = {"plant": "GliderPlant", "observer": "GliderObserver", "controller": "GliderController"}
#: ``simulate``'s FMU folder unless one is given: None, the per-user cache
#: (:func:`glider_cosim.build.cache_dir`), never the current folder
DEFAULT_FMU_DIR: Path | None = None
DISTURBANCE_INPUTS = ("plant.F_x", "plant.F_z", "plant.M_y")


def default_connections(feedback: str = "observer", observer: bool = True) -> list[tuple[str, str]]:
    """The closed loop: plant -> observer -> controller -> plant (and -> observer)."""
    conns = [("controller.delta_cmd", "plant.delta_cmd")]
    if observer:
        conns += [
            ("plant.theta_meas", "observer.theta_meas"),
            ("controller.delta_cmd", "observer.delta_cmd"),
        ]
    if feedback == "state":
        conns += [("plant.V", "controller.V_hat"), ("plant.theta_g", "controller.theta_g_hat")]
    else:
        conns += [
            ("observer.V_hat", "controller.V_hat"),
            ("observer.theta_g_hat", "controller.theta_g_hat"),
        ]
    return conns


def system_for(scenario: Scenario, fmu_dir: Path, step: float | None = None) -> System:
    """The :class:`System` a scenario describes (FMUs from ``fmu_dir`` unless swapped),
    run at ``step`` (s; default the scenario's): the observer's ``f_sample`` follows it
    unless the scenario sets it (:func:`~glider_cosim.scenario.with_sampling`)."""
    fmus = {
        inst: Path(scenario.fmus.get(inst, fmu_dir / f"{name}.fmu"))
        for inst, name in FMU_NAMES.items()
        if scenario.observer or inst != "observer"
    }
    driven = dict.fromkeys(DISTURBANCE_INPUTS, 0.0)
    driven.update(scenario.inputs)
    return System(
        fmus=fmus,
        connections=default_connections(scenario.feedback, scenario.observer),
        parameters=with_sampling(
            scenario.parameters,
            step if step is not None else scenario.step,
            scenario.source,
            has_our_observer(scenario),
        ),
        driven=driven,
        disturbances=list(scenario.disturbances),
        events=[type(e)(**{**e.__dict__}) for e in scenario.events],
        record=scenario.record,
    )


class ArrayRecorder:
    """Keeps rows in a preallocated-in-chunks list (for the API)."""

    def __init__(self) -> None:
        self.columns: list[str] = []
        self.rows: list[Sequence[float]] = []  # rows handed one by one
        self._blocks: list[np.ndarray] = []  # earlier rows, as arrays

    def start(self, columns: Sequence[str]) -> None:
        self.columns = list(columns)

    def row(self, values: Sequence[float]) -> None:
        self.rows.append(values)

    def rows_block(self, values: Any, nrows: int, ncol: int) -> None:
        """``nrows`` rows of ``ncol`` doubles from a buffer (copied)."""
        self._gather(ncol)
        block = np.frombuffer(values, dtype=float, count=nrows * ncol).reshape(nrows, ncol)
        self._blocks.append(block.copy())

    def _gather(self, ncol: int) -> None:
        if self.rows:
            self._blocks.append(np.array(self.rows, dtype=float).reshape(-1, ncol))
            self.rows = []

    def __len__(self) -> int:
        return len(self.rows) + sum(len(b) for b in self._blocks)

    def close(self) -> None:
        pass

    def array(self, n_columns: int | None = None) -> np.ndarray:
        n = len(self.columns) if self.columns else (n_columns or 0)
        self._gather(n)
        if not self._blocks:
            return np.empty((0, n))
        if len(self._blocks) > 1:
            self._blocks = [np.concatenate(self._blocks)]
        return self._blocks[0].copy()


class CsvRecorder:
    """Streams rows to a CSV file (constant memory); ``close`` flushes.

    Values are written with 17 significant digits (``%.17g``: every float64 reads back
    bit for bit). Where the C helper of :mod:`glider_cosim.fastloop` is available, rows
    are collected in blocks of :attr:`BLOCK` and formatted there (the same text as
    Python's ``%`` formatting, about half the time); otherwise in Python.
    """

    BLOCK = 128  # rows formatted at once by the C helper

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._f = None
        self.n_rows = 0
        self._lib = None
        self._pending = 0

    def start(self, columns: Sequence[str]) -> None:
        from .fastloop import library

        self._f = open(self.path, "wb", buffering=1 << 16)  # noqa: SIM115
        self._f.write((",".join(columns) + "\n").encode())
        self._ncol = len(columns)
        self._fmt = ",".join(["%.17g"] * len(columns)) + "\n"
        self._lib = library() if columns else None
        if self._lib is not None:
            self._block = (ctypes.c_double * (self.BLOCK * self._ncol))()
            self._buf = ctypes.create_string_buffer(self.BLOCK * self._ncol * 26 + 16)

    def row(self, values: Sequence[float]) -> None:
        if self._lib is None:
            self._f.write((self._fmt % tuple(values)).encode())
        else:
            i = self._pending * self._ncol
            self._block[i : i + self._ncol] = values
            self._pending += 1
            if self._pending == self.BLOCK:
                self._flush()
        self.n_rows += 1

    def rows_block(self, values: Any, nrows: int, ncol: int) -> None:
        """``nrows`` rows of ``ncol`` doubles from a ctypes buffer (the fast loop's)."""
        if self._lib is None:
            for j in range(nrows):
                self.row(values[j * ncol : (j + 1) * ncol])
            return
        size = ctypes.sizeof(ctypes.c_double)
        j = 0
        while j < nrows:
            take = min(self.BLOCK - self._pending, nrows - j)
            dst = ctypes.addressof(self._block) + self._pending * ncol * size
            ctypes.memmove(dst, ctypes.addressof(values) + j * ncol * size, take * ncol * size)
            self._pending += take
            self.n_rows += take
            j += take
            if self._pending == self.BLOCK:
                self._flush()

    def _flush(self) -> None:
        if not self._pending:
            return
        n = self._lib.glider_format_rows(self._block, self._pending, self._ncol, self._buf,
                                         len(self._buf))  # fmt: skip
        if n < 0:  # cannot happen (26 bytes a value suffice), but never lose rows
            rows = self._block[: self._pending * self._ncol]
            text = "".join(self._fmt % tuple(rows[k : k + self._ncol])
                           for k in range(0, len(rows), self._ncol))  # fmt: skip
            self._f.write(text.encode())
        else:
            self._f.write(ctypes.string_at(self._buf, n))
        self._pending = 0

    def close(self) -> None:
        if self._f is not None:
            if self._lib is not None:
                self._flush()
            self._f.close()
            self._f = None


@dataclass
class RunResult:
    """Outcome of a run: the trajectory, its metrics, and how it ended.

    ``status`` is ``"ok"``, ``"stopped"`` (an FMU discarded the step, e.g. a stall) or
    ``"error"`` (an FMU error/fatal); ``message`` says which instance, call and time.
    """

    scenario: Scenario
    columns: list[str]
    data: np.ndarray
    metrics: dict[str, Any]
    status: str = "ok"
    message: str = ""
    files: dict[str, Path] = field(default_factory=dict)

    def column(self, name: str) -> np.ndarray:
        """One column by name (e.g. ``"plant.theta_g"``)."""
        try:
            return self.data[:, self.columns.index(name)]
        except ValueError:
            raise KeyError(f"no column '{name}' (columns: {', '.join(self.columns)})") from None


def origin_of(scenario: Scenario, ssp: bool = False) -> Callable[[str], str]:
    """``instance.variable`` (or ``event[i]``) -> where its value came from."""

    def origin(ref: str) -> str:
        if ref in scenario.origins:
            return scenario.origins[ref]
        if ssp:
            inst, _, name = ref.partition(".")
            return f"{scenario.source}: component '{inst}'" + (
                f": parameter '{name}'" if name else ""
            )
        if ref.startswith("event["):
            return f"{scenario.source}: key {ref}"
        if ref in scenario.inputs:
            return f"{scenario.source}: key 'inputs.{ref}'"
        return f"{scenario.source}: key '{ref}'"

    return origin


def skip_optional(sim: CoSimulation, scenario: Scenario) -> list[str]:
    """Drop what a swapped-in FMU lacks and the scenario does not need; return the notes.

    Optional: the disturbance inputs (``plant.F_x``, ``F_z``, ``M_y``) when the scenario
    drives none of them (no ``inputs``, disturbance or event on them), and recorded
    variables of a swapped instance (``[fmus]``) that its FMU lacks. :func:`simulate`
    logs each note (logger ``glider_cosim.runner``, level WARNING) once the system is
    loaded. Everything else stays required:
    :meth:`~glider_cosim.master.CoSimulation.load` names a missing connection.
    """
    notes = []
    used = set(scenario.inputs) | {d.target for d in scenario.disturbances}
    used |= {t for e in scenario.events for t in e.actions}
    for ref in DISTURBANCE_INPUTS:
        inst, _, name = ref.partition(".")
        i = sim.instances.get(inst)
        if i is not None and name not in i.vars and ref not in used and ref in sim.system.driven:
            del sim.system.driven[ref]
            notes.append(
                f"{inst} ({quote(i.md.modelName)}) has no input {name}: skipped (the scenario "
                "applies no disturbance to it)"
            )
    if sim.system.record is not None:
        kept = []
        for ref in sim.system.record:
            inst, _, name = ref.partition(".")
            i = sim.instances.get(inst)
            if inst in scenario.fmus and i is not None and name and name not in i.vars:
                notes.append(
                    f"{inst} ({quote(i.md.modelName)}) has no variable {quote(name)}: not recorded"
                )
                continue
            kept.append(ref)
        sim.system.record = kept
    return notes


def simulate(
    scenario: Scenario | str | Path | None = None,
    out: str | Path | None = None,
    *,
    fmu_dir: str | Path | None = DEFAULT_FMU_DIR,
    build: bool = True,
    coupling: str | None = None,
    step: float | None = None,
    stop_time: float | None = None,
    plots: bool = True,
    max_steps: int = DEFAULT_MAX_STEPS,
    options: dict[str, Any] | None = None,
    results_format: str = "csv",
) -> RunResult:
    """Run a scenario and return its results.

    Parameters
    ----------
    scenario : Scenario, path, shipped name or None
        ``None`` runs the default (paper Sec. 3.3) scenario; a ``.ssp``/``.ssd`` path
        runs an SSP.
    out : path, optional
        Folder for ``results.csv`` (streamed), ``metrics.json`` and PNG plots. Without
        it, nothing is written and the rows are kept in memory.
    fmu_dir : path, optional
        Where the FMUs are (built there first if missing or stale, when ``build``).
        Default: the per-user cache (:func:`glider_cosim.build.cache_dir`), so nothing is
        written outside ``out``.
    coupling, step, stop_time : optional
        Override the scenario's values (``"gauss-seidel"``/``"jacobi"``, s, s).
    plots : bool
        Write the PNG plots (with ``out``).
    max_steps : int
        Most communication steps; a longer run is refused before it starts.
    results_format : {"csv", "parquet"}
        ``results.csv`` (text, 17 significant digits) or ``results.parquet`` (float64 as
        they are; pandas and polars read it; needs pyarrow; about 4 us a row faster here).
    options : dict, optional
        The options to record in ``metrics.json`` (``run.options``; the CLI passes the
        ones given on its command line). Default: the ``coupling``, ``step`` and
        ``stop_time`` given here.

    Returns
    -------
    RunResult
        ``data`` has one row per communication point (the initial one included). A run
        that fails in an FMU (its initialisation included, e.g. an out-of-range
        parameter) returns with status ``"error"`` (``"stopped"`` for fmi2Discard) and
        the FMU's message.

    Raises
    ------
    ScenarioError, SSPError, SystemSpecError, ValueError
        Bad arguments (scenario, SSP or FMU files, names, value types and units, step
        and stop time): raised before any FMU is instantiated.
    OSError
        ``out`` cannot be created or written.
    glider_cosim.master.Interrupted
        A KeyboardInterrupt (SIGINT or SIGTERM during the run), raised after the results
        so far are written (status ``"interrupted"``).
    """
    if scenario is not None and not isinstance(scenario, Scenario | str | Path):
        raise TypeError(
            f"scenario {quote(scenario)} is invalid: expected a Scenario, a path, a shipped "
            "name or None"
        )
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
        raise ValueError(f"max_steps {quote(max_steps)} is invalid: expected an integer >= 1")
    if results_format not in ("csv", "parquet"):
        raise ValueError(
            f"results_format {quote(results_format)} is invalid: expected 'csv' or 'parquet'"
        )
    if results_format == "parquet" and out is not None:
        from .parquet import _pyarrow

        _pyarrow()  # one line now, not after the run
    for key, value in (("step", step), ("stop_time", stop_time)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)):
            raise TypeError(f"{key} {quote(value)} is invalid: expected a number (s)")
    ssp_system = None
    if isinstance(scenario, str | Path) and str(scenario).endswith((".ssp", ".ssd")):
        from .inputs.ssp_files import ssp_name
        from .ssp import load_ssp

        ssp_system, ssp_step, ssp_stop = load_ssp(scenario)
        scenario = Scenario(name=ssp_name(scenario), source=str(scenario), step=ssp_step,
                            stop_time=ssp_stop, parameters=ssp_system.parameters)  # fmt: skip
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    h = step if step is not None else scenario.step
    stop = stop_time if stop_time is not None else scenario.stop_time
    try:
        count_steps(stop, h, max_steps)
    except SystemSpecError as err:
        given = [f"{k} = {quote(v)}" for k, v in (("step", step), ("stop_time", stop_time))
                 if v is not None]  # fmt: skip
        raise SystemSpecError(f"{', '.join(given) or scenario.source}: {err}") from None
    fmu_dir = fmu_folder(fmu_dir)
    if ssp_system is not None:
        system = ssp_system
        if "observer" in system.parameters:  # the SSP sets every value: only check it
            with_sampling(system.parameters, h, scenario.source)
    else:
        if build:
            build_all(fmu_dir, only_stale=True)
        system = system_for(scenario, fmu_dir, h)
    sim = CoSimulation(system, step=h, coupling=coupling or scenario.coupling, max_steps=max_steps)
    origin = origin_of(scenario, ssp_system is not None)

    notes: list[str] = []

    def before_checks(s: CoSimulation) -> None:
        if ssp_system is None:
            notes.extend(skip_optional(s, scenario))
        check_system_values(s, origin)

    try:
        sim.load(before_checks)
    except SystemSpecError as err:
        raise SystemSpecError(f"{scenario.source}: {err}") from None
    for note in notes:  # only for a system that loaded: a refused one gets one line
        log.warning(note)
    files: dict[str, Path] = {}
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        clear_owned(out)  # an earlier run's CSV, metrics and plots: they describe another run
        if results_format == "parquet":
            from .parquet import ParquetRecorder

            files["results"] = out / "results.parquet"
            recorder: Any = ParquetRecorder(files["results"])
        else:
            files["results"] = out / "results.csv"
            recorder = CsvRecorder(files["results"])
    else:
        recorder = ArrayRecorder()
    from .progress import RunProgress, wanted

    if wanted():  # a terminal: the simulated time reached, for runs of more than 2 s
        recorder = RunProgress(recorder, count_steps(stop, h, max_steps) + 1, stop)
    status, message = "ok", ""
    interrupt: Interrupted | None = None
    failure: Exception | None = None
    try:
        sim.run(stop, recorder)
    except FMUStopped as err:
        status, message, failure = "stopped", str(err), err
    except FMUCallError as err:
        status, message, failure = "error", str(err), err
    except SystemSpecError:
        raise
    except MasterError as err:
        status, message, failure = "error", str(err), err
    except KeyboardInterrupt as err:
        interrupt = err if isinstance(err, Interrupted) else Interrupted()
        status, message = "interrupted", interrupt.describe()
    finally:
        recorder.close()
        sim.close()
    if "results" in files and not files["results"].exists():
        del files["results"]  # the run failed before its first row
    if isinstance(recorder, RunProgress):
        recorder = recorder.inner
    if hasattr(recorder, "read"):  # Parquet
        data = recorder.read() if recorder.n_rows else np.empty((0, len(sim.columns)))
        columns = sim.columns
    elif isinstance(recorder, CsvRecorder):
        data = (
            np.loadtxt(files["results"], delimiter=",", skiprows=1, ndmin=2)
            if recorder.n_rows
            else np.empty((0, len(sim.columns)))
        )
        columns = sim.columns
    else:
        columns, data = recorder.columns or sim.columns, recorder.array(len(sim.columns))
    metrics = compute_metrics(columns, data, scenario, sim, status)
    metrics.update(status=status, message=message)
    if options is None:
        options = {k: v for k, v in (("coupling", coupling), ("step", step),
                                     ("stop_time", stop_time)) if v is not None}  # fmt: skip
    metrics["run"] = run_record(scenario, sim, options)
    metrics["events"] = marked_events(sim, status, failure)
    result = RunResult(scenario, columns, data, metrics, status, message, files)
    if out is not None:
        files["metrics"] = out / "metrics.json"
        files["metrics"].write_text(json.dumps(_jsonable(metrics), indent=2) + "\n")
        if plots and len(data) > 1:
            from .plots import write_plots

            files.update(write_plots(result, out))
    if interrupt is not None:
        raise interrupt
    return result


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, np.floating | np.integer):
        return _jsonable(obj.item())
    return obj
