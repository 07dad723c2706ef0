"""A run as ``glider-cosim run`` asks for it: the FMUs prepared, every input checked in
one line before anything is built or instantiated (scenario or SSP, ``--set``, ranges,
step count, output folder, real-time and external options), then :func:`~.run.simulate`;
and the run's summary as the console prints it."""

from __future__ import annotations

import builtins
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..inputs.outputs import UsageError, check_out_dir, os_error
from ..inputs.text import command_line, quote, shown_path
from ..master.errors import Interrupted, SystemSpecError
from ..master.spec import DEFAULT_MAX_STEPS
from .run import RunResult

#: ``max_extract_mb``'s default, MiB
MAX_EXTRACT_MB = 256


def _ssp_origin(source: str, ref: str) -> str:
    inst, _, name = ref.partition(".")
    return f"{source}: component '{inst}'" + (f": parameter '{name}'" if name else "")


def _time(seconds: float | None) -> str:
    """A time for display: rounded to 1 us, shortest form."""
    return "n/a" if seconds is None else f"{round(seconds, 6):.10g}"


def run_checked(
    scenario: str | Path | None = None,
    out: str | Path | None = None,
    *,
    fmu_dir: str | Path | None = None,
    flavor: str | None = None,
    fmi: int | None = None,
    overwrite_fmus: bool = False,
    coupling: str | None = None,
    step: float | None = None,
    stop_time: float | None = None,
    no_plots: bool = False,
    format: str = "csv",  # noqa: A002 (``--format``)
    set: Sequence[str] = (),  # noqa: A002 (``--set``)
    max_steps: int = DEFAULT_MAX_STEPS,
    max_extract_mb: int = MAX_EXTRACT_MB,
    real_time: bool = False,
    rtf: float | None = None,
    max_lateness_ms: float | None = None,
    spin_ms: float | None = None,
    external: Sequence[str] = (),
    external_timeout: float | None = None,
    argv: Sequence[str] | None = None,
) -> RunResult:
    """Check a run's every input, then run it: what ``glider-cosim run`` does, its
    keyword arguments named as its options (``--stop-time``: ``stop_time``).

    Parameters
    ----------
    scenario : path or shipped name, optional
        A TOML file, a shipped scenario's name or a ``.ssp``/``.ssd`` file (default: the
        default scenario).
    out : path, optional
        Results folder (default: ``out/<scenario>``), checked before anything runs.
    fmu_dir, flavor, fmi, overwrite_fmus : optional
        Our FMUs (:func:`glider_cosim.scenarios.system.prepare_asked`); ``flavor="wasm"``
        runs the native FMI 3.0 FMUs' WebAssembly components (``fmi`` 3 or None).
    coupling : {"gauss-seidel", "jacobi"}, optional
        Coupling scheme (default: the scenario's).
    step, stop_time : float, optional
        Communication step and stop time, s (default: the scenario's or the SSP's).
    no_plots : bool
        Skip the PNG plots and ``plots.html``.
    format : {"csv", "parquet"}
        The results file's format.
    set : sequence of str
        ``INSTANCE.NAME=VALUE`` overrides (not for an SSP).
    max_steps : int
        Most communication steps.
    max_extract_mb : int
        Most MiB one FMU or SSP archive may unpack to.
    real_time : bool
        Pace the communication points to the wall clock; ``rtf`` (real-time factor, 1),
        ``max_lateness_ms`` (ms) and ``spin_ms`` (ms) need it.
    external : sequence of str
        ``COMPONENT=udp://HOST:PORT``: endpoints outside the process, over the
        scenario's ``[external]``; ``external_timeout``: their silence allowed, s.
    argv : sequence of str, optional
        The command line as given, named by an interrupted run's "run it again with".

    Returns
    -------
    RunResult
        As :func:`~.run.simulate` returns it.

    Raises
    ------
    UsageError, ScenarioError, SSPError, ValueError
        Bad input, in one line naming the option, before anything is run.
    glider_cosim.master.Interrupted
        Ctrl-C or SIGTERM; its ``kept`` says where the results are and how to go on.
    """
    from ..inputs.archives import set_extract_limit
    from ..inputs.check import check_ranges, our_kinds
    from ..master.spec import count_steps
    from ..scenarios.system import prepare_asked
    from .run import origin_of, simulate

    wasm = flavor == "wasm"
    if wasm:  # the native FMI 3.0 FMUs, run as their WebAssembly components
        if fmi == 2:
            raise UsageError("--flavor wasm runs FMI 3.0 components: expected --fmi 3 or none")
        flavor, fmi = "native", 3
        from ..master.wasm import use_components

        use_components(True)
    try:
        folder = prepare_asked(fmu_dir, flavor, fmi, overwrite_fmus=overwrite_fmus,
                               host_only=True, scenario=scenario, swaps=True)  # fmt: skip
        set_extract_limit(max_extract_mb * 2**20)
        if scenario and str(scenario).endswith((".ssp", ".ssd")):
            if set:
                raise UsageError("--set does not apply to an SSP (edit its parameter values)")
            from ..inputs.ssp_files import ssp_name
            from ..interop.ssp_import import load_ssp

            # checks the SSP before anything runs; step/stop_time stand in for what it lacks
            system, ssp_step, stop = load_ssp(scenario, step=step, stop_time=stop_time)
            run: Any = scenario
            name, source = ssp_name(scenario), shown_path(scenario)
            # our FMUs inside: their parameter tables' ranges
            check_ranges(system.parameters, lambda ref: _ssp_origin(source, ref),
                         kinds=our_kinds(system.fmus))  # fmt: skip
        else:
            run = _with_sets(scenario, set)
            # our FMUs' valid ranges, before anything is built or instantiated
            check_ranges(run.parameters, origin_of(run), builtins.set(run.fmus), run.events)
            name, source, ssp_step, stop = run.name, run.source, run.step, run.stop_time
        given = [(o, v) for o, v in (("--step", step), ("--stop-time", stop_time)) if v]
        try:
            count_steps(stop_time or stop, step or ssp_step, max_steps)
        except SystemSpecError as err:
            where = " and ".join(f"{o} {v:g}" for o, v in given) or source
            raise UsageError(f"{where}: {err}") from None
        out = Path(out) if out is not None else Path("out") / name  # one rule
        check_out_dir(out, "--out")
        options = {
            opt: value
            for opt, value, default in (
                ("--coupling", coupling, None),
                ("--step", step, None),
                ("--stop-time", stop_time, None),
                ("--fmu-dir", fmu_dir, None),
                ("--flavor", "wasm" if wasm else flavor, None),
                ("--fmi", fmi, None),
                ("--no-plots", no_plots, False),
                ("--max-steps", max_steps, DEFAULT_MAX_STEPS),
                ("--max-extract-mb", max_extract_mb, MAX_EXTRACT_MB),
                ("--format", format, "csv"),
                ("--real-time", real_time, False),
                ("--rtf", rtf, None),
                ("--max-lateness-ms", max_lateness_ms, None),
                ("--spin-ms", spin_ms, None),
                ("--external", list(external), []),
                ("--external-timeout", external_timeout, None),
            )
            if value != default
        }
        pacing = _real_time(real_time, rtf, max_lateness_ms, spin_ms)
        endpoints = _externals(run, external, external_timeout)
        try:
            return simulate(run, out, fmu_dir=folder,
                            build=fmu_dir is not None,  # the cache's: checked once, above
                            coupling=coupling, step=step, stop_time=stop_time,
                            plots=not no_plots, max_steps=max_steps, options=options,
                            results_format=format, real_time=pacing,
                            external=endpoints)  # fmt: skip
        except OSError as err:
            raise os_error(err, {"--out": out, "--fmu-dir": Path(folder)}) from None
        except Interrupted as err:  # the console's last line: where the rows are, what next
            m = getattr(err.result, "metrics", None) or {}
            rows = (
                f"{m['rows']} rows to t = {_time(m.get('end_time_s'))} s in " if "rows" in m else ""
            )
            again = f"; run it again with: {command_line(argv)}" if argv is not None else ""
            err.kept = f"{rows}{out}{again}"
            raise
    finally:
        if wasm:
            from ..master.wasm import use_components

            use_components(False)


def _with_sets(scenario: str | Path | None, sets: Sequence[str]) -> Any:
    """The scenario, with ``--set`` overrides applied and their origins recorded."""
    from ..scenarios.overrides import apply_overrides, parse_sets
    from ..scenarios.scenario import load_scenario

    loaded = load_scenario(scenario)
    if sets:
        loaded = apply_overrides(loaded, parse_sets(list(sets)))
        for item in sets:
            loaded.origins[item.partition("=")[0].strip()] = f"--set {quote(item)}"
    return loaded


def _real_time(real_time: bool, rtf: float | None, max_lateness_ms: float | None,
               spin_ms: float | None) -> Any:  # fmt: skip
    """``--real-time``'s pacing, or None; refuses --rtf, --max-lateness-ms and --spin-ms
    without it."""
    from ..realtime.pacing import SPIN_MS, RealTime

    given = (("--rtf", rtf), ("--max-lateness-ms", max_lateness_ms), ("--spin-ms", spin_ms))
    if not real_time:
        for opt, value in given:
            if value is not None:
                raise UsageError(f"{opt} needs --real-time")
        return None
    return RealTime(rtf or 1.0, max_lateness_ms, SPIN_MS if spin_ms is None else spin_ms)


def _externals(scenario: Any, external: Sequence[str], timeout: float | None) -> dict:
    """``--external`` over the scenario's ``[external]``: component -> endpoint."""
    given = dict(getattr(scenario, "external", None) or {})
    if not given and not external:
        return {}
    from ..realtime.external import Endpoint, parse_external

    given.update(parse_external(list(external)))
    return {
        name: Endpoint(url, timeout=timeout) if timeout else Endpoint(url)
        for name, url in given.items()
    }


def describe_run(result: RunResult) -> str:
    """The run's summary as ``glider-cosim run`` prints it: scenario, rows, coupling and
    step; the ``--set`` values with their units; rise, settling, overshoot, effort; the
    outcome; the real-time pacing; the files written (lines, no final newline)."""
    from ..fmus.variables import overrides_echo
    from .metrics import describe_outcome
    from .provenance import overrides_text

    m, scenario = result.metrics, result.scenario
    deg = 57.29577951308232

    def fmt(key: str, scale: float = 1.0, unit: str = "") -> str:
        v = m.get(key)
        return "n/a" if v is None else f"{v * scale:.3f}{unit}"

    overrides = f" with {overrides_text(m)}" if overrides_text(m) else ""
    lines = [
        f"scenario {scenario.name} ({scenario.source}){overrides}"
        + f": {m['rows']} rows to t = {_time(m['end_time_s'])} s, coupling {m['coupling']}, "
        f"step {_time(m['step_s'])} s"
    ]
    if getattr(scenario, "overrides", None):  # with units, from the model descriptions
        fmus = {k: f["file"] for k, f in (m.get("run") or {}).get("fmus", {}).items()}
        lines.append(f"  set: {overrides_echo(scenario.overrides, fmus)}")
    lines.append(
        f"  rise {fmt('rise_time_s', unit=' s')}, settling {fmt('settling_time_s', unit=' s')}"
        f", overshoot {fmt('overshoot_rad', deg, ' deg')}, effort "
        f"{fmt('control_effort', unit=' rad s')}, max |delta_cmd| "
        f"{fmt('max_abs_delta_cmd_rad', deg, ' deg')}"
    )
    lines.append(f"  outcome: {describe_outcome(m)}")
    if "real_time" in m:
        from ..realtime.pacing import describe

        lines.append(f"  {describe(m['real_time'])}")
    lines.append(f"  wrote {', '.join(str(f) for f in result.files.values())}")
    return "\n".join(lines)
