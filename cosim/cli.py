"""``glider-cosim``: build the FMUs, run scenarios, analyse the closed loop.

Exit codes: 0 success, 1 the run stopped or failed in an FMU (results up to the failure
are written), 2 bad input (arguments, scenario, FMU files), 130 interrupted.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path

from .master import MasterError, SystemSpecError
from .scenario import ScenarioError, shipped_scenarios


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit code 2
        self.exit(2, f"{self.prog}: error: {message}\n")


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not v > 0 or v != v or v == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r} is invalid: expected a finite number > 0")
    return v


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="glider-cosim", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    b = sub.add_parser("build", help="build the three FMUs")
    b.add_argument("--out", default="fmus", help="output folder (default: fmus)")

    r = sub.add_parser("run", help="run a scenario (default: the paper's Sec. 3.3 case)")
    r.add_argument(
        "scenario",
        nargs="?",
        default=None,
        help=f"TOML file or shipped name ({', '.join(shipped_scenarios())}); default: default",
    )
    r.add_argument("--out", default="out", help="results folder (default: out/<scenario>)")
    r.add_argument("--fmu-dir", default="fmus", help="FMU folder (built if missing or stale)")
    r.add_argument("--coupling", choices=("gauss-seidel", "jacobi"), default=None)
    r.add_argument("--step", type=_positive, default=None, help="communication step, s")
    r.add_argument("--stop-time", type=_positive, default=None, help="stop time, s")
    r.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    r.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="INSTANCE.NAME=VALUE",
        help="override a parameter (repeatable): controller.K_c=6, plant.theta_g_0='-30 deg'",
    )

    e = sub.add_parser("export-ssp", help="write the system as an SSP 1.0 archive")
    e.add_argument("out", help="output .ssp file")
    e.add_argument("scenario", nargs="?", default=None, help="scenario (default: default)")
    e.add_argument("--fmu-dir", default="fmus", help="FMU folder (built if missing or stale)")

    sub.add_parser("host-env", help="environment a C/C++ host needs for our FMUs")

    xf = sub.add_parser("export-fmu", help="the closed loop as one co-simulation FMU")
    xf.add_argument("out", help="output .fmu file")
    xf.add_argument("scenario", nargs="?", default=None, help="scenario (default: default)")
    xf.add_argument("--fmu-dir", default="fmus", help="FMU folder (built if missing or stale)")

    rep = sub.add_parser("report", help="run every figure's scenario and write report.md")
    rep.add_argument("--out", default="out/report", help="report folder (default: out/report)")
    rep.add_argument("--fmu-dir", default="fmus", help="FMU folder (built if missing or stale)")
    rep.add_argument("--no-progress", action="store_true", help="no progress bar")
    rep.add_argument("--roa-grid", default="7x5", metavar="NxM|none",
                     help="region-of-attraction grid: N glide angles x M speeds (default "
                     "7x5; none: skip the map)")  # fmt: skip
    rep.add_argument("--workers", type=int, default=2, help="local Dask workers for the map")
    rep.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")

    a = sub.add_parser("analyze", help="equilibrium, eigenvalues, stable K_c range")
    a.add_argument("--json", action="store_true", help="one JSON object on stdout")

    from .sweep import add_parser as add_sweep_parser

    add_sweep_parser(sub)
    sub.add_parser("scenarios", help="list the shipped scenarios")
    return p


def _run(args: argparse.Namespace) -> int:
    from .metrics import describe_outcome
    from .report import apply_overrides
    from .runner import simulate
    from .scenario import load_scenario, parse_sets

    if args.scenario and str(args.scenario).endswith((".ssp", ".ssd")):
        if args.set:
            raise ScenarioError("--set does not apply to an SSP (edit its parameter values)")
        from .ssp import load_ssp

        load_ssp(args.scenario)  # checks the SSP before anything runs
        scenario = args.scenario
        name = Path(args.scenario).stem
    else:
        scenario = load_scenario(args.scenario)
        if args.set:
            scenario = apply_overrides(scenario, parse_sets(args.set))
        name = scenario.name
    out = Path(args.out)
    if args.out == "out":
        out = out / name
    result = simulate(
        scenario,
        out,
        fmu_dir=args.fmu_dir,
        coupling=args.coupling,
        step=args.step,
        stop_time=args.stop_time,
        plots=not args.no_plots,
    )
    m = result.metrics
    scenario = result.scenario
    deg = 57.29577951308232

    def fmt(key: str, scale: float = 1.0, unit: str = "") -> str:
        v = m.get(key)
        return "n/a" if v is None else f"{v * scale:.3f}{unit}"

    print(
        f"scenario {scenario.name} ({scenario.source}): {m['rows']} rows to "
        f"t = {m['end_time_s']} s, coupling {m['coupling']}, step {m['step_s']} s"
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
        print(f"glider-cosim: run {result.status}: {result.message}", file=sys.stderr)
        return 1
    return 0


def _report(args: argparse.Namespace) -> int:
    from .report import build_report

    try:
        from .analysis import analyze
    except ImportError:  # pragma: no cover - analysis is part of the package
        analyze = None
    from .roa import parse_grid

    grid = None if args.roa_grid.lower() == "none" else parse_grid(args.roa_grid)
    if args.workers < 1:
        raise ValueError(f"--workers {args.workers}: expected a number >= 1")
    path = build_report(args.out, args.fmu_dir, analysis=analyze, progress=not args.no_progress,
                        roa_grid=grid, workers=args.workers, scheduler=args.scheduler)  # fmt: skip
    print(f"wrote {path}")
    return 0


def _analyze(args: argparse.Namespace) -> int:
    from .analysis import analyze, format_report

    result = analyze()
    if args.json:
        print(json.dumps(result))
    else:
        print(format_report(result))
    return 0


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"glider-cosim: warning: {message}", file=sys.stderr if file is None else file)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``glider-cosim`` console script (warnings: one line each)."""
    args = build_parser().parse_args(argv)
    with warnings.catch_warnings():
        warnings.showwarning = _one_line_warning
        return _main(args)


def _main(args: argparse.Namespace) -> int:
    try:
        if args.command == "build":
            from .build import build_all

            for name, path in build_all(args.out).items():
                print(f"{name}: {path}")
            code = 0
        elif args.command == "run":
            code = _run(args)
        elif args.command == "export-fmu":
            from .onefmu import export_one_fmu

            print(f"wrote {export_one_fmu(args.out, args.scenario, args.fmu_dir)}")
            code = 0
        elif args.command == "host-env":
            from .hostenv import main as host_env_main

            code = host_env_main()
        elif args.command == "export-ssp":
            from .ssp import export_ssp

            print(f"wrote {export_ssp(args.out, args.scenario, args.fmu_dir)}")
            code = 0
        elif args.command == "sweep":
            from .sweep import main as sweep_main

            code = sweep_main(args)
        elif args.command == "report":
            code = _report(args)
        elif args.command == "analyze":
            code = _analyze(args)
        else:
            print("\n".join(shipped_scenarios()))
            code = 0
    except (ScenarioError, SystemSpecError, ValueError) as err:
        print(f"glider-cosim: error: {err}", file=sys.stderr)
        code = 2
    except MasterError as err:
        print(f"glider-cosim: error: {err}", file=sys.stderr)
        code = 1
    except KeyboardInterrupt:
        print("glider-cosim: interrupted; results so far are written", file=sys.stderr)
        code = 130
    except OSError as err:
        print(f"glider-cosim: error: {err}", file=sys.stderr)
        code = 2
    return code


def console_main() -> None:
    """Console script: run :func:`main`, flush, and exit with its code.

    The process leaves with ``os._exit`` once everything is written: after FMUs ran, a
    rare abort ("corrupted double-linked list") can still come from native libraries'
    exit-time finalisers (seen in OpenBLAS's and libgfortran's, about 1 exit in 100-400);
    nothing is lost by skipping them.
    """
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    console_main()
