"""Run a scenario on the three glider FMUs: the Python API behind ``glider-cosim run``."""

from __future__ import annotations

import json
import logging
import math
import sys
from array import array
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..figures.plots import PlotError, write_plots
from ..fmus.folders import build_all, fmu_folder
from ..inputs.check import check_system_values
from ..inputs.ssp_files import ssp_name
from ..inputs.text import one_line, quote
from ..interop.ssp_import import load_ssp
from ..master.cosimulation import CoSimulation
from ..master.errors import (
    FMUCallError,
    FMUStopped,
    Interrupted,
    MasterError,
    SystemSpecError,
)
from ..master.spec import DEFAULT_MAX_STEPS, count_steps
from ..realtime.pacing import Pacer, RealTime, TooLate, paced_run
from ..scenarios.overrides import override_scenario
from ..scenarios.sampling import with_sampling
from ..scenarios.scenario import Scenario, load_scenario
from ..scenarios.system import DISTURBANCE_INPUTS, fit_swapped, swapped, system_for
from .metrics import compute_metrics
from .provenance import clear_owned, marked_events, replaced_note, run_record
from .recorders import ArrayRecorder, CsvRecorder, Table

if TYPE_CHECKING:
    import numpy as np

log = logging.getLogger(__name__)


#: ``simulate``'s FMU folder unless one is given: None, the per-user cache
#: (:func:`glider_cosim.fmus.folders.cache_dir`), never the current folder
DEFAULT_FMU_DIR: Path | None = None


class ArrayOnAccess:
    """A dataclass field (``RunResult.data``) set to a
    :class:`~glider_cosim.runner.recorders.Table` or an array and read as a numpy array,
    made on first access (the run itself needs no numpy)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.slot = "_" + name

    def __get__(self, obj: Any, objtype: type | None = None) -> Any:
        if obj is None:
            raise AttributeError(self.slot[1:])  # no default for the dataclass field
        value = obj.__dict__[self.slot]
        if isinstance(value, Table):
            value = obj.__dict__[self.slot] = value.array()
        return value

    def __set__(self, obj: Any, value: Any) -> None:
        obj.__dict__[self.slot] = value


@dataclass
class RunResult:
    """Outcome of a run: the trajectory, its metrics, and how it ended.

    ``status`` is ``"ok"``, ``"stopped"`` (an FMU discarded the step, e.g. a stall) or
    ``"error"`` (an FMU error/fatal); ``message`` says which instance, call and time.
    ``data`` is a 2-D numpy array (one row per communication point, ``columns`` wide),
    made on first access from the rows the run kept (the run itself, its metrics and
    files need no numpy).
    """

    scenario: Scenario
    columns: list[str]
    data: np.ndarray = ArrayOnAccess()  # type: ignore[assignment]
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
    variables of a swapped instance (``[fmus]``) that its FMU lacks. A swapped controller
    or estimator is wired by :func:`~glider_cosim.scenarios.system.loop_wiring`: its
    optional inputs (``V_hat``, ...) are connected when it declares them, its other
    inputs by name. :func:`simulate` logs each note (logger ``glider_cosim.runner.run``,
    level WARNING) once the system is loaded. Everything else stays required:
    :meth:`~glider_cosim.master.CoSimulation.load` names a missing connection.
    """
    notes = fit_swapped(sim, set(scenario.fmus))
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
    overrides: Mapping[str, Any] | None = None,
    fmu_dir: str | Path | None = DEFAULT_FMU_DIR,
    build: bool = True,
    coupling: str | None = None,
    step: float | None = None,
    stop_time: float | None = None,
    plots: bool = True,
    max_steps: int = DEFAULT_MAX_STEPS,
    options: dict[str, Any] | None = None,
    results_format: str = "csv",
    real_time: RealTime | None = None,
    external: dict[str, Any] | None = None,
) -> RunResult:
    """Run a scenario and return its results.

    Parameters
    ----------
    scenario : Scenario, path, shipped name or None
        ``None`` runs the default (paper Sec. 3.3) scenario; a ``.ssp``/``.ssd`` path
        runs an SSP.
    out : path, optional
        Folder for ``results.csv`` (streamed), ``metrics.json`` and PNG plots, written
        straight into it (what an earlier run wrote there is replaced; one made with
        other settings is named in a warning first). Without it, nothing is written and
        the rows are kept in memory.
    overrides : mapping, optional
        ``{"controller.K_c": 6, "plant.theta_g_0": "-30 deg", "plant.V_0": "0.2 m/s"}``:
        what ``--set`` takes, as numbers, booleans or strings (a value in the variable's
        declared unit, ``deg`` for an angle, a law name for ``controller.law``), checked
        as ``--set`` is before anything is built; recorded in ``metrics.json``
        (``run.overrides``). Not for an SSP.
    fmu_dir : path, optional
        Where the FMUs are (built there first if missing or stale, when ``build``).
        Default: the per-user cache (:func:`glider_cosim.fmus.folders.cache_dir`), so nothing is
        written outside ``out``.
    coupling, step, stop_time : optional
        Override the scenario's values (``"gauss-seidel"``/``"jacobi"``, s, s).
    plots : bool
        Write the PNG plots and ``plots.html`` (with ``out``), in this process, after
        ``results.csv`` and ``metrics.json`` (:func:`draw_plots`).
    max_steps : int
        Most communication steps; a longer run is refused before it starts.
    results_format : {"csv", "parquet"}
        ``results.csv`` (text: each value as ``repr`` writes it, exact) or
        ``results.parquet`` (float64 as they are; pandas and polars read it; needs
        pyarrow; about 0.5 us a row faster here).
    real_time : RealTime, optional
        Pace the communication points to the wall clock
        (:mod:`glider_cosim.realtime.pacing`); ``metrics.json`` gains ``real_time``.
    external : dict, optional
        Instances served by an endpoint outside the process: name -> ``udp://HOST:PORT``
        or an :class:`~glider_cosim.realtime.external.Endpoint`
        (:mod:`glider_cosim.realtime.external`).
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
        and stop time, ``overrides``): raised before any FMU is instantiated.
    OSError
        ``out`` cannot be created or written.
    PlotError
        A PNG plot cannot be written (an OSError; the results and ``metrics.json`` are
        written).
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
        from .parquet import require_pyarrow

        require_pyarrow()  # one line now, not after the run
    for key, value in (("step", step), ("stop_time", stop_time)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)):
            raise TypeError(f"{key} {quote(value)} is invalid: expected a number (s)")
    ssp_system = None
    if isinstance(scenario, str | Path) and str(scenario).endswith((".ssp", ".ssd")):
        ssp_system, ssp_step, ssp_stop = load_ssp(scenario, step=step, stop_time=stop_time)
        scenario = Scenario(name=ssp_name(scenario), source=str(scenario), step=ssp_step,
                            stop_time=ssp_stop, parameters=ssp_system.parameters)  # fmt: skip
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if overrides:
        if ssp_system is not None:
            raise ValueError("overrides do not apply to an SSP (edit its parameter values)")
        scenario = override_scenario(scenario, overrides)
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
            build_all(fmu_dir, only_stale=True, skip=swapped(scenario))
        system = system_for(scenario, fmu_dir, h)
    sim = CoSimulation(system, step=h, coupling=coupling or scenario.coupling, max_steps=max_steps)
    origin = origin_of(scenario, ssp_system is not None)

    notes: list[str] = []
    pacer = None if real_time is None else Pacer(h, real_time, sim.t0)

    def before_checks(s: CoSimulation) -> None:
        if external:
            from ..realtime.external import attach

            attach(s, external, pacer)
        if ssp_system is None:
            notes.extend(skip_optional(s, scenario))
        check_system_values(s, origin)

    try:
        sim.load(before_checks)
    except SystemSpecError as err:
        raise SystemSpecError(f"{scenario.source}: {err}") from None
    if ssp_system is None and scenario.fmus:
        from .probe import late_notes

        notes.extend(late_notes(dict(scenario.fmus)))  # a swapped controller, probed alone
    for note in notes:  # only for a system that loaded: a refused one gets one line
        log.warning(note)
    if options is None:
        options = {k: v for k, v in (("coupling", coupling), ("step", step),
                                     ("stop_time", stop_time)) if v is not None}  # fmt: skip
    record = run_record(scenario, sim, options)
    files: dict[str, Path] = {}
    if out is not None:
        out = Path(out)
        note = replaced_note(out, record)  # earlier results made otherwise: say so, once
        if note is not None:
            log.warning(note)
        out.mkdir(parents=True, exist_ok=True)
        clear_owned(out)  # an earlier run's CSV, metrics and plots: they describe another run
        if results_format == "parquet":
            from .parquet import ParquetRecorder

            files["results"] = out / "results.parquet"
            recorder: Any = ParquetRecorder(files["results"])
        else:
            files["results"] = out / "results.csv"
            recorder = CsvRecorder(files["results"], keep=ArrayRecorder())
    else:
        recorder = ArrayRecorder()
    from ..progress import RunProgress, mode

    if mode() != "off":  # the simulated time reached, for runs of more than 2 s
        wall = None if real_time is None else (stop - sim.t0) / real_time.rtf
        recorder = RunProgress(recorder, count_steps(stop, h, max_steps) + 1, stop, wall)
    status, message = "ok", ""
    interrupt: Interrupted | None = None
    failure: Exception | None = None
    try:
        if pacer is not None:
            paced_run(sim, stop, recorder, pacer)
        else:
            sim.run(stop, recorder)
    except (FMUStopped, TooLate) as err:  # a discard, or later than --max-lateness-ms
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
    empty = Table(array("d"), 0, len(sim.columns))
    if hasattr(recorder, "read"):  # Parquet
        data: Any = recorder.read() if recorder.n_rows else empty
        columns = sim.columns
    elif isinstance(recorder, CsvRecorder):
        data = (
            recorder.keep.table(len(sim.columns))
            if recorder.n_rows and recorder.keep is not None
            else empty
        )
        columns = sim.columns
    else:
        columns, data = recorder.columns or sim.columns, recorder.table(len(sim.columns))
    metrics = compute_metrics(columns, data, scenario, sim, status)
    metrics.update(status=status, message=message)
    ext = {n: e.summary() for n, e in getattr(sim, "external", {}).items()}
    if ext:
        metrics["external"] = ext
    if pacer is not None:
        metrics["real_time"] = {**pacer.summary(), **({"external": ext} if ext else {})}
    metrics["run"] = record
    metrics["events"] = marked_events(sim, status, failure)
    result = RunResult(scenario, columns, data, metrics, status, message, files)
    if out is not None:
        files["metrics"] = out / "metrics.json"
        files["metrics"].write_text(json.dumps(_jsonable(metrics), indent=2) + "\n")
        if plots and len(data) > 1:
            files.update(draw_plots(result, out))
    if interrupt is not None:
        interrupt.result = result  # what was kept, for the console's last line
        raise interrupt
    return result


def draw_plots(result: RunResult, out: Path) -> dict[str, Path]:
    """Draw a run's PNG plots (:func:`~glider_cosim.figures.plots.write_plots`, with
    matplotlib) and write its ``plots.html`` from the same specs
    (:func:`~glider_cosim.figures.pages.write_run_page`, bokeh) into ``out``, in this
    process, once its results and ``metrics.json`` are written.

    Parameters
    ----------
    result : RunResult
        The run's rows and metrics.
    out : Path
        The run's output folder.

    Returns
    -------
    dict of str to Path
        ``{plot name: PNG, ..., "page": plots.html}`` of the files written (no ``"page"``
        when it could not be written: a logged warning, e.g. bokeh missing).

    Raises
    ------
    PlotError
        A PNG could not be drawn or written: one line naming the file (the run's results
        and ``metrics.json`` are kept).
    """
    from ..figures.pages import write_run_page
    from ..progress import home, say

    say(f"run: drawing the plots into {home(out)}")  # importing matplotlib takes a while
    specs: list[dict[str, Any]] = []
    try:
        files = write_plots(result, out, keep=specs)
    except (OSError, ValueError, RuntimeError) as err:
        why = one_line(f"{type(err).__name__}: {err}")
        raise PlotError(f"PNG plots not written ({why}); the run's results and metrics.json "
                        "are kept") from err  # fmt: skip
    return files | write_run_page(result, out, specs)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    np = sys.modules.get("numpy")  # a numpy scalar only if numpy was imported
    if np is not None and isinstance(obj, np.floating | np.integer):
        return _jsonable(obj.item())
    return obj
