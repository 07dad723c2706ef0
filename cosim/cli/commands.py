"""What each subcommand does, once its arguments are parsed."""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
from pathlib import Path

from ..components import component
from ..fmus.folders import default_dir
from ..inputs.text import command_line, one_line, prefix, quote, shown_path
from ..master.errors import Interrupted, SystemSpecError
from ..master.spec import DEFAULT_MAX_STEPS
from ..scenarios.scenario import shipped_scenarios
from . import compare, webassembly
from .parser import UsageError, uses_fmu_options

log = logging.getLogger(__name__)


def _check_out_dir(path: Path, option: str) -> None:
    """Refuse an output folder that cannot be created or written (naming the option)."""
    shown = f"{option} {quote(str(path))}"
    if path.exists() and not path.is_dir():
        raise UsageError(f"{shown}: exists and is not a folder: expected a folder")
    parent = path
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise UsageError(f"{shown}: {quote(str(parent))} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UsageError(f"{shown}: {quote(str(parent))} is not writable")


def _check_out_file(path: Path, option: str, suffix: str) -> None:
    """Refuse an output file that is a folder, does not end in ``suffix``, is in a folder
    that does not exist, or cannot be created (naming the option)."""
    shown = f"{option} {quote(str(path))}"
    if path.is_dir():
        raise UsageError(f"{shown}: is a folder: expected a file name")
    if path.suffix.lower() != suffix:
        raise UsageError(f"{shown}: expected a file name ending in {suffix}")
    if not path.parent.is_dir() and not path.parent.exists():
        raise UsageError(f"{shown}: folder {quote(str(path.parent))} does not exist: expected "
                         "an existing folder (create it first)")  # fmt: skip
    _check_out_dir(path.parent, option)


#: the file each export writes
EXPORT_SUFFIX = {"export-fmu": ".fmu", "export-ssp": ".ssp"}


def _os_error(err: OSError, paths: dict[str, Path]) -> UsageError:
    """An OSError as a one-line error naming the option whose path it concerns."""
    reason = err.strerror or one_line(err)
    filename = str(err.filename or "")
    for option, path in paths.items():
        if filename and (filename == str(path) or filename.startswith(f"{path}{os.sep}")):
            return UsageError(f"{option} {quote(str(path))}: {reason} ({quote(filename)})")
    option, path = next(iter(paths.items()))
    where = f" ({quote(filename)})" if filename else ""
    return UsageError(f"{option} {quote(str(path))}: {reason}{where}")


def _ssp_origin(source: str, ref: str) -> str:
    inst, _, name = ref.partition(".")
    return f"{source}: component '{inst}'" + (f": parameter '{name}'" if name else "")


def _time(seconds: float | None) -> str:
    """A time for display: rounded to 1 us, shortest form."""
    return "n/a" if seconds is None else f"{round(seconds, 6):.10g}"


def _run(args: argparse.Namespace) -> int:
    from ..fmus.variables import overrides_echo
    from ..inputs.archives import set_extract_limit
    from ..inputs.check import check_ranges, our_kinds
    from ..master.spec import count_steps
    from ..runner.metrics import describe_outcome
    from ..runner.provenance import overrides_text
    from ..runner.run import origin_of, simulate
    from ..scenarios.overrides import apply_overrides, parse_sets
    from ..scenarios.scenario import load_scenario

    set_extract_limit(args.max_extract_mb * 2**20)
    if args.scenario and str(args.scenario).endswith((".ssp", ".ssd")):
        if args.set:
            raise UsageError("--set does not apply to an SSP (edit its parameter values)")
        from ..inputs.ssp_files import ssp_name
        from ..interop.ssp_import import load_ssp

        # checks the SSP before anything runs; --step/--stop-time stand in for what it lacks
        system, step, stop = load_ssp(args.scenario, step=args.step, stop_time=args.stop_time)
        scenario = args.scenario
        name, source = ssp_name(args.scenario), shown_path(args.scenario)
        # our FMUs inside: their parameter tables' ranges
        check_ranges(system.parameters, lambda ref: _ssp_origin(source, ref),
                     kinds=our_kinds(system.fmus))  # fmt: skip
    else:
        scenario = load_scenario(args.scenario)
        if args.set:
            overrides = parse_sets(args.set)
            scenario = apply_overrides(scenario, overrides)
            for item in args.set:
                scenario.origins[item.partition("=")[0].strip()] = f"--set {quote(item)}"
        # our FMUs' valid ranges, before anything is built or instantiated
        check_ranges(scenario.parameters, origin_of(scenario), set(scenario.fmus), scenario.events)
        name, source, step, stop = scenario.name, scenario.source, scenario.step, scenario.stop_time
    given = [(o, v) for o, v in (("--step", args.step), ("--stop-time", args.stop_time)) if v]
    try:
        count_steps(args.stop_time or stop, args.step or step, args.max_steps)
    except SystemSpecError as err:
        where = " and ".join(f"{o} {v:g}" for o, v in given) or source
        raise UsageError(f"{where}: {err}") from None
    out = Path(args.out) if args.out is not None else Path("out") / name  # one rule
    _check_out_dir(out, "--out")
    options = {
        opt: value
        for opt, value, default in (
            ("--coupling", args.coupling, None),
            ("--step", args.step, None),
            ("--stop-time", args.stop_time, None),
            ("--fmu-dir", getattr(args, "fmu_dir_given", args.fmu_dir), None),
            ("--flavor", "wasm" if args.run_wasm else getattr(args, "flavor", None), None),
            ("--fmi", getattr(args, "fmi", None), None),
            ("--no-plots", args.no_plots, False),
            ("--max-steps", args.max_steps, DEFAULT_MAX_STEPS),
            ("--max-extract-mb", args.max_extract_mb, 256),
            ("--format", args.format, "csv"),
            ("--real-time", args.real_time, False),
            ("--rtf", args.rtf, None),
            ("--max-lateness-ms", args.max_lateness_ms, None),
            ("--spin-ms", args.spin_ms, None),
            ("--external", args.external, []),
            ("--external-timeout", args.external_timeout, None),
        )
        if value != default
    }
    real_time = _real_time(args)
    external = _externals(args, scenario)
    try:
        result = simulate(
            scenario,
            out,
            fmu_dir=args.fmu_dir,
            build=args.fmu_dir_given is not None,  # the cache's: checked once, by dispatch
            coupling=args.coupling,
            step=args.step,
            stop_time=args.stop_time,
            plots=not args.no_plots,
            max_steps=args.max_steps,
            options=options,
            results_format=args.format,
            real_time=real_time,
            external=external,
        )
    except OSError as err:
        raise _os_error(err, {"--out": out, "--fmu-dir": Path(args.fmu_dir)}) from None
    except Interrupted as err:  # the console's last line: where the rows are, what next
        m = getattr(err.result, "metrics", None) or {}
        rows = f"{m['rows']} rows to t = {_time(m.get('end_time_s'))} s in " if "rows" in m else ""
        err.kept = f"{rows}{out}; run it again with: {command_line(getattr(args, 'argv', []))}"
        raise
    m, scenario = result.metrics, result.scenario
    deg = 57.29577951308232

    def fmt(key: str, scale: float = 1.0, unit: str = "") -> str:
        v = m.get(key)
        return "n/a" if v is None else f"{v * scale:.3f}{unit}"

    overrides = f" with {overrides_text(m)}" if overrides_text(m) else ""
    print(
        f"scenario {scenario.name} ({scenario.source}){overrides}"
        + f": {m['rows']} rows to t = {_time(m['end_time_s'])} s, coupling {m['coupling']}, "
        f"step {_time(m['step_s'])} s"
    )
    if getattr(scenario, "overrides", None):  # with units, from the model descriptions
        fmus = {k: f["file"] for k, f in (m.get("run") or {}).get("fmus", {}).items()}
        print(f"  set: {overrides_echo(scenario.overrides, fmus)}")
    print(
        f"  rise {fmt('rise_time_s', unit=' s')}, settling {fmt('settling_time_s', unit=' s')}"
        f", overshoot {fmt('overshoot_rad', deg, ' deg')}, effort "
        f"{fmt('control_effort', unit=' rad s')}, max |delta_cmd| "
        f"{fmt('max_abs_delta_cmd_rad', deg, ' deg')}"
    )
    print(f"  outcome: {describe_outcome(m)}")
    if "real_time" in m:
        from ..realtime.pacing import describe

        print(f"  {describe(m['real_time'])}")
    print(f"  wrote {', '.join(str(f) for f in result.files.values())}")
    if result.status != "ok":
        print(f"{prefix('error', 'run')}run {result.status}: {one_line(result.message)}",
              file=sys.stderr)  # fmt: skip
        return 1
    return 0


def _real_time(args: argparse.Namespace):
    """``--real-time``'s pacing, or None; refuses --rtf, --max-lateness-ms and --spin-ms
    without it."""
    from ..realtime.pacing import SPIN_MS, RealTime

    given = (("--rtf", args.rtf), ("--max-lateness-ms", args.max_lateness_ms),
             ("--spin-ms", args.spin_ms))  # fmt: skip
    if not args.real_time:
        for opt, value in given:
            if value is not None:
                raise UsageError(f"{opt} needs --real-time")
        return None
    spin = SPIN_MS if args.spin_ms is None else args.spin_ms
    return RealTime(args.rtf or 1.0, args.max_lateness_ms, spin)


def _externals(args: argparse.Namespace, scenario) -> dict:
    """``--external`` over the scenario's ``[external]``: component -> endpoint."""
    given = dict(getattr(scenario, "external", None) or {})
    if not given and not args.external:
        return {}
    from ..realtime.external import Endpoint, parse_external

    given.update(parse_external(args.external))
    timeout = args.external_timeout
    return {
        name: Endpoint(url, timeout=timeout) if timeout else Endpoint(url)
        for name, url in given.items()
    }


def _serve(args: argparse.Namespace) -> int:
    from ..fmus.folders import prepare_fmus
    from ..realtime.serve import serve

    if args.fmu is not None:
        fmu, what = Path(args.fmu), shown_path(args.fmu)
    else:
        name = component(args.component).model
        fmu = prepare_fmus(None, args.flavor, host_only=True) / f"{name}.fmu"
        what = f"{fmu.name}, {args.flavor}"

    def ready(addr: tuple[str, int]) -> None:
        print(f"serving {args.component} ({what}) on udp://{addr[0]}:{addr[1]}", flush=True)

    try:
        serve(fmu, args.listen, once=args.once, ready=ready)
    except KeyboardInterrupt:
        return 130
    return 0


def _report(args: argparse.Namespace) -> int:
    from ..studies.analysis import analyze
    from ..studies.report import build_report
    from ..studies.roa import parse_grid

    grid = None if args.roa_grid.lower() == "none" else parse_grid(args.roa_grid)
    if args.workers < 1:
        raise ValueError(f"--workers {args.workers}: expected a number >= 1")
    written: list[Path] = []
    path = build_report(args.out, args.fmu_dir, analysis=analyze, progress=not args.no_progress,
                        roa_grid=grid, workers=args.workers, scheduler=args.scheduler,
                        page=not args.no_plots, written=written,
                        command=command_line(args.argv))  # fmt: skip
    print(f"wrote {path}")
    page = next((f for f in written if f.name == "report.html"), None)
    if page is not None:
        print(f"wrote {page} (the figures to zoom and hover: open it in a browser)")
    return 0


def _analyze(args: argparse.Namespace) -> int:
    from ..studies.analysis import analyze, format_report

    result = analyze(
        plant_fmu=Path(args.fmu_dir) / f"{component('plant').model}.fmu" if args.from_fmu else None
    )
    if args.json:
        print(json.dumps(result))
    else:
        print(format_report(result))
    return 0


def runs_here(args: argparse.Namespace) -> bool:
    """True if the command runs our FMUs here alone (run, sweep or report without a Dask
    scheduler, analyze): the host-only set serves it (exports hand every platform's on)."""
    here = ("run", "sweep", "report", "analyze", "compare")
    return args.command in here and not getattr(args, "scheduler", None)


def dispatch(args: argparse.Namespace) -> int:
    """Run the parsed subcommand; its exit code."""
    # --fmu-dir/--flavor: the folder (default: the per-user cache), built in the flavor
    # asked; verify builds ours only for --write-references/--export
    if args.command in EXPORT_SUFFIX:  # before any FMU is built for it
        _check_out_file(Path(args.out), "OUT", EXPORT_SUFFIX[args.command])
    if args.command == "sweep":  # up front, as run's: before any build and before Dask
        _check_out_dir(Path(args.out), "--out")
    if (code := webassembly.dispatch(args, _check_out_dir)) is not None:  # wasm, explore
        return code
    if uses_fmu_options(args):  # analyze only with --from-fmu, verify builds its own
        from ..fmus.folders import cache_root, prepare_fmus

        folder = Path(args.fmu_dir) if args.fmu_dir is not None else None
        if folder is not None and not folder.exists():  # a typo builds a whole new set
            log.warning(f"--fmu-dir {quote(str(folder))} does not exist: a fresh set of "
                        "FMUs is built there")  # fmt: skip
        args.fmu_dir_given = args.fmu_dir  # what the user said, for the run record
        from ..scenarios.system import swapped_in  # a user's FMU in --fmu-dir, swapped in

        swaps = folder is not None and args.command in ("run", "sweep", "export-ssp", "compare")
        skip = swapped_in(args.scenario) if swaps else set()
        try:
            fmi, here = getattr(args, "fmi", None), runs_here(args)
            args.fmu_dir = str(prepare_fmus(folder, args.flavor, fmi, host_only=here,
                                            overwrite=args.overwrite_fmus, skip=skip))  # fmt: skip
        except OSError as err:
            raise _os_error(err, {"--fmu-dir": folder or cache_root()}) from None
    if args.command == "build":
        from ..fmus.folders import build_all

        out = Path(args.out) if args.out is not None else default_dir(args.flavor, args.fmi)
        _check_out_dir(out, "--out")
        if args.compiler is not None:  # every build step and hash of this process uses it
            from glider_fmi.toolchain import COMPILER_ENV

            os.environ[COMPILER_ENV] = args.compiler
        from glider_fmi.toolchain import ToolchainError

        try:
            built = build_all(out, flavor=args.flavor, fmi=args.fmi,
                              overwrite=args.overwrite_fmus, option="--out")  # fmt: skip
        except ToolchainError as err:  # a compiler chosen is missing or failed
            raise UsageError(str(err)) from None
        except OSError as err:
            raise _os_error(err, {"--out": out}) from None
        for name, path in built.items():
            print(f"{name}: {path}")
        return 0
    if args.command == "run":
        return _run(args)
    if args.command == "serve":
        return _serve(args)
    if args.command == "build-onboard":
        from ..realtime.onboard import build_onboard

        print(f"wrote {build_onboard(Path(args.out), args.target)}")
        return 0
    if args.command in ("export-fmu", "export-ssp"):
        out = Path(args.out)
        if args.command == "export-fmu":
            from ..interop.onefmu import export_one_fmu as export
        else:
            from functools import partial

            from ..interop.ssp_export import export_ssp

            export = partial(export_ssp, ssp_version=args.ssp_version)
        try:
            print(f"wrote {export(out, args.scenario, args.fmu_dir)}")
        except OSError as err:
            raise _os_error(err, {"OUT": out, "--fmu-dir": Path(args.fmu_dir)}) from None
        return 0
    if args.command == "host-env":
        from ..interop.hostenv import main as host_env_main

        return host_env_main(["--config"] if args.config else [])
    if args.command == "sweep":
        from ..sweeps.sweep import main as sweep_main

        return sweep_main(args)
    if args.command == "report":
        _check_out_dir(Path(args.out), "--out")
        return _report(args)
    if args.command == "analyze":
        return _analyze(args)
    if args.command in ("verify", "add-experiments"):
        from ..verify.command import run_command

        if getattr(args, "export", None):
            _check_out_dir(Path(args.export), "--export")
        return run_command(args)
    if args.command == "compare":
        return compare.run(args, _check_out_dir)
    if args.command == "cache":
        from ..fmus.cache import cache_report

        cache_report(args.prune)
        return 0
    from ..scenarios.scenario import load_scenario, one_line_summary

    names = shipped_scenarios()
    width = max(len(n) for n in names)
    for name in names:
        print(f"{name:<{width}}  {one_line_summary(load_scenario(name))}")
    return 0
