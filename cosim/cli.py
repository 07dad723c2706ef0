"""glider-cosim: build the FMUs, run scenarios, analyse the closed loop.

Exit codes: 0 success, 1 the run stopped or failed in an FMU (results up to the failure
are written), 2 bad input (arguments, scenario, SSP, FMU files; one line), 130
interrupted by Ctrl-C, 143 terminated by SIGTERM (results so far are written).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import re
import signal
import sys
import threading
import warnings
from collections.abc import Sequence
from pathlib import Path

from glider_cosim.build.folders import FLAVORS, FMI_VERSIONS, add_fmu_options, default_dir
from glider_cosim.inputs.text import one_line, quote, shown_path
from glider_cosim.master.errors import Interrupted, MasterError, SystemSpecError
from glider_cosim.master.spec import DEFAULT_MAX_STEPS
from glider_cosim.scenarios.scenario import ScenarioError, shipped_scenarios


class UsageError(ValueError):
    """A command-line argument cannot be used (the message names the option)."""


class _Formatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Plain-text help: defaults shown, reST markup of the docstrings removed."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        return super()._fill_text(_plain(text), width, indent)

    def _get_help_string(self, action: argparse.Action) -> str:
        text = _plain(action.help or "")
        if action.default in (None, False, [], argparse.SUPPRESS) or "%(default)" in text:
            return text
        if "default" in text:
            return text
        return text + " (default: %(default)s)"


def _plain(text: str) -> str:
    text = re.sub(r":\w+:`~?([^`]+)`", r"\1", text)
    return text.replace("``", "'")


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", _Formatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> None:  # one line, exit code 2
        self.exit(2, f"{self.prog}: error: {one_line(message)}\n")


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{quote(text)} is not a number") from None
    if not v > 0 or v != v or v == float("inf"):
        raise argparse.ArgumentTypeError(f"{quote(text)} is invalid: expected a finite number > 0")
    return v


def _count(text: str) -> int:
    if not re.fullmatch(r"\+?\d{1,18}", text.strip()) or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{quote(text)} is invalid: expected an integer >= 1")
    return int(text)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="glider-cosim", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    b = sub.add_parser("build", help="build the three FMUs", description="Build the three FMUs.")
    b.add_argument(
        "--out",
        default=None,
        help="output folder (default: fmus, fmus/native for native, fmus/fmi3 and "
        "fmus/fmi3/native with --fmi 3)",
    )
    b.add_argument(
        "--flavor", choices=FLAVORS, default="python", help="Python reference or native C99"
    )
    b.add_argument(
        "--fmi", type=int, choices=FMI_VERSIONS, default=2, help="FMI version: 2.0 or 3.0"
    )

    r = sub.add_parser(
        "run",
        help="run a scenario or an SSP (default: the paper's Sec. 3.3 case)",
        description="Run a TOML scenario, a shipped scenario or an SSP (.ssp archive, .ssd\n"
        "file) with our master; write results.csv, metrics.json and PNG plots.",
    )
    r.add_argument(
        "scenario",
        nargs="?",
        default=None,
        help=f"TOML file, shipped name ({', '.join(shipped_scenarios())}) or .ssp/.ssd "
        "file; default: default",
    )
    r.add_argument("--out", default="out", help="results folder ('out' means out/<scenario>)")
    add_fmu_options(r, fmi=True)
    r.add_argument(
        "--coupling",
        type=str.lower,
        choices=("gauss-seidel", "jacobi"),
        default=None,
        help="coupling scheme (default: the scenario's, gauss-seidel for an SSP)",
    )
    r.add_argument(
        "--step",
        type=_positive,
        default=None,
        help="communication step, s (default: the scenario's)",
    )
    r.add_argument(
        "--stop-time", type=_positive, default=None, help="stop time, s (default: the scenario's)"
    )
    r.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    r.add_argument(
        "--format",
        choices=("csv", "parquet"),
        default="csv",
        help="results file: results.csv (text) or results.parquet (binary float64, read by "
        "pandas and polars; needs pyarrow)",
    )
    r.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="INSTANCE.NAME=VALUE",
        help="override a parameter (repeatable): controller.K_c=6, plant.theta_g_0='-30 deg'",
    )
    r.add_argument(
        "--max-steps", type=_count, default=DEFAULT_MAX_STEPS, help="most communication steps"
    )
    r.add_argument(
        "--max-extract-mb",
        type=_count,
        default=256,
        help="most MiB one FMU or SSP archive may unpack to",
    )

    e = sub.add_parser("export-ssp", help="write the system as an SSP 1.0 archive")
    e.add_argument("out", help="output .ssp file")
    e.add_argument("scenario", nargs="?", default=None, help="scenario; default: default")
    add_fmu_options(e, fmi=True)

    he = sub.add_parser(
        "host-env", help="environment a C/C++ host on another machine needs for our FMUs"
    )
    he.add_argument(
        "--config",
        action="store_true",
        help="print the FMU runtime's Python configuration instead (for GLIDER_FMI_PYTHON_CONFIG)",
    )

    xf = sub.add_parser("export-fmu", help="the closed loop as one co-simulation FMU")
    xf.add_argument("out", help="output .fmu file")
    xf.add_argument("scenario", nargs="?", default=None, help="scenario; default: default")
    add_fmu_options(xf)

    rep = sub.add_parser("report", help="run every figure's scenario and write report.md")
    rep.add_argument("--out", default="out/report", help="report folder")
    add_fmu_options(rep)
    rep.add_argument("--no-progress", action="store_true", help="no progress bar")
    rep.add_argument("--roa-grid", default="7x5", metavar="NxM|none",
                     help="region-of-attraction grid: N glide angles x M speeds (default "
                     "7x5; none: skip the map)")  # fmt: skip
    rep.add_argument("--workers", type=int, default=2, help="local Dask workers for the map")
    rep.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")

    a = sub.add_parser("analyze", help="equilibrium, eigenvalues, stable K_c range")
    a.add_argument("--json", action="store_true", help="one JSON object on stdout")

    from glider_cosim.sweeps.sweep import add_parser as add_sweep_parser

    add_sweep_parser(sub)
    from glider_cosim.verify.kit import _tolerance
    from glider_cosim.verify.kit import add_arguments as add_verify_arguments

    v = sub.add_parser(
        "verify",
        help="run the component verification kit on an FMU",
        description="Run the reference cases of a component (plant, observer, controller) on\n"
        "an FMI 2.0 co-simulation FMU and compare with the references; exit 0 if every case\n"
        "passes, 1 if any fails, 2 on bad input.",
    )
    add_verify_arguments(v, _tolerance)
    sub.add_parser("scenarios", help="list the shipped scenarios")
    return p


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


def _check_out_file(path: Path, option: str) -> None:
    """Refuse an output file that is a folder or cannot be created (naming the option)."""
    if path.is_dir():
        raise UsageError(f"{option} {quote(str(path))}: is a folder: expected a file name")
    _check_out_dir(path.parent, option)


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
    from glider_cosim.inputs.archives import set_extract_limit
    from glider_cosim.inputs.check import check_ranges, our_kinds
    from glider_cosim.master.spec import count_steps
    from glider_cosim.runner.metrics import describe_outcome
    from glider_cosim.runner.run import origin_of, simulate
    from glider_cosim.scenarios.overrides import apply_overrides
    from glider_cosim.scenarios.scenario import load_scenario, parse_sets

    set_extract_limit(args.max_extract_mb * 2**20)
    if args.scenario and str(args.scenario).endswith((".ssp", ".ssd")):
        if args.set:
            raise UsageError("--set does not apply to an SSP (edit its parameter values)")
        from glider_cosim.inputs.ssp_files import ssp_name
        from glider_cosim.interop.ssp_import import load_ssp

        system, step, stop = load_ssp(args.scenario)  # checks the SSP before anything runs
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
    out = Path(args.out)
    if args.out == "out":
        out = out / name
    _check_out_dir(out, "--out")
    options = {
        opt: value
        for opt, value, default in (
            ("--coupling", args.coupling, None),
            ("--step", args.step, None),
            ("--stop-time", args.stop_time, None),
            ("--fmu-dir", getattr(args, "fmu_dir_given", args.fmu_dir), None),
            ("--flavor", getattr(args, "flavor", None), None),
            ("--fmi", getattr(args, "fmi", None), None),
            ("--no-plots", args.no_plots, False),
            ("--max-steps", args.max_steps, DEFAULT_MAX_STEPS),
            ("--max-extract-mb", args.max_extract_mb, 256),
            ("--format", args.format, "csv"),
        )
        if value != default
    }
    try:
        result = simulate(
            scenario,
            out,
            fmu_dir=args.fmu_dir,
            coupling=args.coupling,
            step=args.step,
            stop_time=args.stop_time,
            plots=not args.no_plots,
            max_steps=args.max_steps,
            options=options,
            results_format=args.format,
        )
    except OSError as err:
        raise _os_error(err, {"--out": out, "--fmu-dir": Path(args.fmu_dir)}) from None
    m = result.metrics
    scenario = result.scenario
    deg = 57.29577951308232

    def fmt(key: str, scale: float = 1.0, unit: str = "") -> str:
        v = m.get(key)
        return "n/a" if v is None else f"{v * scale:.3f}{unit}"

    print(
        f"scenario {scenario.name} ({scenario.source}): {m['rows']} rows to "
        f"t = {_time(m['end_time_s'])} s, coupling {m['coupling']}, step {_time(m['step_s'])} s"
    )
    print(
        f"  rise {fmt('rise_time_s', unit=' s')}, settling {fmt('settling_time_s', unit=' s')}"
        f", overshoot {fmt('overshoot_rad', deg, ' deg')}, effort "
        f"{fmt('control_effort', unit=' rad s')}, max |delta_cmd| "
        f"{fmt('max_abs_delta_cmd_rad', deg, ' deg')}"
    )
    print(f"  outcome: {describe_outcome(m)}")
    print(f"  wrote {', '.join(str(f) for f in result.files.values())}")
    if result.status != "ok":
        print(f"glider-cosim: run {result.status}: {one_line(result.message)}", file=sys.stderr)
        return 1
    return 0


def _report(args: argparse.Namespace) -> int:
    from glider_cosim.studies.report import build_report

    try:
        from glider_cosim.studies.analysis import analyze
    except ImportError:  # pragma: no cover - analysis is part of the package
        analyze = None
    from glider_cosim.studies.roa import parse_grid

    grid = None if args.roa_grid.lower() == "none" else parse_grid(args.roa_grid)
    if args.workers < 1:
        raise ValueError(f"--workers {args.workers}: expected a number >= 1")
    path = build_report(args.out, args.fmu_dir, analysis=analyze, progress=not args.no_progress,
                        roa_grid=grid, workers=args.workers, scheduler=args.scheduler)  # fmt: skip
    print(f"wrote {path}")
    return 0


def _analyze(args: argparse.Namespace) -> int:
    from glider_cosim.studies.analysis import analyze, format_report

    result = analyze()
    if args.json:
        print(json.dumps(result))
    else:
        print(format_report(result))
    return 0


def _terminate(signum: int, frame: object) -> None:
    raise Interrupted(signum)


class _NoteHandler(logging.Handler):
    """Warnings of our modules as one-line notes on the current ``sys.stderr``."""

    def emit(self, record: logging.LogRecord) -> None:
        sys.stderr.write(f"glider-cosim: note: {one_line(record.getMessage())}\n")


def _notes_to_stderr() -> None:
    """Warnings of our modules (e.g. a skipped optional connection) as one-line notes."""
    logger = logging.getLogger("glider_cosim")
    if not any(isinstance(h, _NoteHandler) for h in logger.handlers):
        handler = _NoteHandler(logging.WARNING)
        logger.addHandler(handler)


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"glider-cosim: warning: {message}", file=sys.stderr if file is None else file)


def _private_matplotlib_cache() -> None:
    """matplotlib's font cache in this process's temporary folder, not ``~/.cache``: a
    command writes nothing outside its output and FMU folders (unless the user points
    ``MPLCONFIGDIR`` somewhere). Rebuilding the cache costs about 0.1 s of CPU."""
    if "MPLCONFIGDIR" not in os.environ and "matplotlib" not in sys.modules:
        from glider_cosim.inputs.tempdirs import new_temp_dir

        os.environ["MPLCONFIGDIR"] = str(new_temp_dir("matplotlib_"))


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``glider-cosim`` console script (returns the exit code; notes and
    warnings one line each)."""
    args = build_parser().parse_args(argv)
    _notes_to_stderr()
    _private_matplotlib_cache()
    with warnings.catch_warnings():
        warnings.showwarning = _one_line_warning
        return _main(args)


def _main(args: argparse.Namespace) -> int:
    old_term = None
    if threading.current_thread() is threading.main_thread():
        old_term = signal.signal(signal.SIGTERM, _terminate)  # cleaned up like Ctrl-C
    try:
        code = _dispatch(args)
    except (ScenarioError, SystemSpecError, ValueError) as err:
        print(f"glider-cosim: error: {one_line(err)}", file=sys.stderr)
        code = 2
    except MasterError as err:
        print(f"glider-cosim: error: {one_line(err)}", file=sys.stderr)
        code = 1
    except KeyboardInterrupt as err:
        if isinstance(err, Interrupted) and err.signum == signal.SIGTERM:
            print("glider-cosim: terminated (SIGTERM); results so far are written",
                  file=sys.stderr)  # fmt: skip
            code = 143
        else:
            print("glider-cosim: interrupted; results so far are written", file=sys.stderr)
            code = 130
    except OSError as err:
        print(f"glider-cosim: error: {one_line(err)}", file=sys.stderr)
        code = 2
    except RecursionError:
        print("glider-cosim: error: input nested too deeply", file=sys.stderr)
        code = 2
    finally:
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
    return code


def _dispatch(args: argparse.Namespace) -> int:
    # --fmu-dir/--flavor: the folder (default: the per-user cache), built in the flavor
    # asked; verify builds ours only for --write-references/--export
    if hasattr(args, "fmu_dir") and args.command != "verify" and hasattr(args, "flavor"):
        from glider_cosim.build.folders import cache_root, prepare_fmus

        folder = Path(args.fmu_dir) if args.fmu_dir is not None else None
        args.fmu_dir_given = args.fmu_dir  # what the user said, for the run record
        try:
            args.fmu_dir = str(prepare_fmus(folder, args.flavor, getattr(args, "fmi", None)))
        except OSError as err:
            raise _os_error(err, {"--fmu-dir": folder or cache_root()}) from None
    if args.command == "build":
        from glider_cosim.build.folders import build_all

        out = Path(args.out) if args.out is not None else default_dir(args.flavor, args.fmi)
        _check_out_dir(out, "build --out")
        try:
            built = build_all(out, flavor=args.flavor, fmi=args.fmi)
        except OSError as err:
            raise _os_error(err, {"build --out": out}) from None
        for name, path in built.items():
            print(f"{name}: {path}")
        return 0
    if args.command == "run":
        return _run(args)
    if args.command in ("export-fmu", "export-ssp"):
        out = Path(args.out)
        _check_out_file(out, f"{args.command} OUT")
        if args.command == "export-fmu":
            from glider_cosim.interop.onefmu import export_one_fmu as export
        else:
            from glider_cosim.interop.ssp_export import export_ssp as export
        try:
            print(f"wrote {export(out, args.scenario, args.fmu_dir)}")
        except OSError as err:
            raise _os_error(
                err, {f"{args.command} OUT": out, "--fmu-dir": Path(args.fmu_dir)}
            ) from None
        return 0
    if args.command == "host-env":
        from glider_cosim.interop.hostenv import main as host_env_main

        return host_env_main(["--config"] if args.config else [])
    if args.command == "sweep":
        from glider_cosim.sweeps.sweep import main as sweep_main

        return sweep_main(args)
    if args.command == "report":
        _check_out_dir(Path(args.out), "report --out")
        return _report(args)
    if args.command == "analyze":
        return _analyze(args)
    if args.command == "verify":
        from glider_cosim.verify.kit import run_command

        if args.export:
            _check_out_dir(Path(args.export), "verify --export")
        return run_command(args)
    print("\n".join(shipped_scenarios()))
    return 0


def console_main() -> None:
    """Console script: run :func:`main` and exit with its code (a normal interpreter exit)."""
    sys.exit(main())


if __name__ == "__main__":
    console_main()
