"""What each subcommand does, once its arguments are parsed: each a few lines over one
library call, its options passed as that call's keyword arguments (:func:`_kwargs`)."""

from __future__ import annotations

import argparse
import inspect
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..components import component
from ..inputs.outputs import UsageError, check_out_dir, check_out_file, os_error
from ..inputs.text import one_line, prefix


def _kwargs(args: argparse.Namespace, call: Callable[..., Any]) -> dict[str, Any]:
    """The parsed options that are keyword parameters of ``call`` (``--stop-time``:
    ``stop_time``)."""
    names = inspect.signature(call).parameters
    return {k: v for k, v in vars(args).items() if k in names}


def runs_here(args: argparse.Namespace) -> bool:
    """True if the command runs our FMUs here alone (run, sweep or report without a Dask
    scheduler, analyze): the host-only set serves it (exports hand every platform's on)."""
    here = ("run", "sweep", "report", "analyze", "compare")
    return args.command in here and not getattr(args, "scheduler", None)


def _fmus(args: argparse.Namespace) -> str:
    """The FMU folder the shared options ``--fmu-dir``/``--flavor``/``--fmi``/
    ``--overwrite-fmus`` ask for, built if missing or stale."""
    from ..scenarios.system import prepare_asked

    swaps = args.command in ("run", "sweep", "export-ssp", "compare")
    return str(prepare_asked(args.fmu_dir, args.flavor, getattr(args, "fmi", None),
                             overwrite_fmus=args.overwrite_fmus, host_only=runs_here(args),
                             scenario=getattr(args, "scenario", None), swaps=swaps))  # fmt: skip


def _build(args: argparse.Namespace) -> int:
    from ..fmus.folders import build

    for name, path in build(**_kwargs(args, build)).items():
        print(f"{name}: {path}")
    return 0


def _run(args: argparse.Namespace) -> int:
    from ..runner.checked import describe_run, run_checked

    result = run_checked(**_kwargs(args, run_checked))
    print(describe_run(result))
    if result.status != "ok":
        print(f"{prefix('error', 'run')}run {result.status}: {one_line(result.message)}",
              file=sys.stderr)  # fmt: skip
        return 1
    return 0


def _serve(args: argparse.Namespace) -> int:
    from ..fmus.folders import prepare_fmus
    from ..inputs.text import shown_path
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


def _build_onboard(args: argparse.Namespace) -> int:
    from ..realtime.onboard import build_onboard

    print(f"wrote {build_onboard(Path(args.out), args.target)}")
    return 0


def _export(args: argparse.Namespace) -> int:
    out = Path(args.out)
    check_out_file(out, "OUT", ".fmu" if args.command == "export-fmu" else ".ssp")
    fmu_dir = _fmus(args)
    if args.command == "export-fmu":
        from ..interop.onefmu import export_one_fmu as export
    else:
        from functools import partial

        from ..interop.ssp_export import export_ssp

        export = partial(export_ssp, ssp_version=args.ssp_version)
    try:
        print(f"wrote {export(out, args.scenario, fmu_dir)}")
    except OSError as err:
        raise os_error(err, {"OUT": out, "--fmu-dir": Path(fmu_dir)}) from None
    return 0


def _host_env(args: argparse.Namespace) -> int:
    from ..interop.hostenv import main as host_env_main

    return host_env_main(["--config"] if args.config else [])


def _sweep(args: argparse.Namespace) -> int:
    from ..sweeps.sweep import sweep

    check_out_dir(Path(args.out), "--out")  # up front, as run's: before any build and Dask
    return sweep(**_kwargs(args, sweep) | {"fmu_dir": _fmus(args)})


def _report(args: argparse.Namespace) -> int:
    from ..studies.report import report

    path, *others = report(**_kwargs(args, report) | {"fmu_dir": _fmus(args)})
    print(f"wrote {path}")
    for page in (f for f in others if f.name == "report.html"):
        print(f"wrote {page} (the figures to zoom and hover: open it in a browser)")
    return 0


def _explore(args: argparse.Namespace) -> int:
    from ..runner.explore import explore

    page = explore(**_kwargs(args, explore))
    print(f"wrote {page} (open this file in a browser; no server needed)")
    return 0


def _analyze(args: argparse.Namespace) -> int:
    from ..studies.analysis import analyze, format_report

    plant = None
    if args.from_fmu:
        plant = Path(_fmus(args)) / f"{component('plant').model}.fmu"
    elif given := [o for o in ("fmu_dir", "flavor", "fmi") if getattr(args, o) is not None]:
        raise UsageError(f"--{given[0].replace('_', '-')} needs --from-fmu (the model's "
                         "own Jacobian uses no FMU)")  # fmt: skip
    result = analyze(plant_fmu=plant)
    print(json.dumps(result) if args.json else format_report(result))
    return 0


def _verify(args: argparse.Namespace) -> int:
    from ..verify.command import verify_command

    return verify_command(**_kwargs(args, verify_command))


def _add_experiments(args: argparse.Namespace) -> int:
    from ..verify.lsref_add import add_experiments

    print(f"wrote {add_experiments(args.fmu, args.case, args.out, args.role, args.fmu_dir)}")
    return 0


def _compare(args: argparse.Namespace) -> int:
    from ..studies.compare import compare, describe

    print(describe(compare(args.scenario, args.out, _fmus(args))))
    return 0


def _scenarios(args: argparse.Namespace) -> int:
    from ..scenarios.scenario import describe_shipped

    print(describe_shipped())
    return 0


def _cache(args: argparse.Namespace) -> int:
    from ..fmus.cache import cache_report

    cache_report(args.prune)
    return 0


#: each command's function
COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {
    "build": _build,
    "run": _run,
    "serve": _serve,
    "build-onboard": _build_onboard,
    "export-ssp": _export,
    "host-env": _host_env,
    "export-fmu": _export,
    "report": _report,
    "explore": _explore,
    "analyze": _analyze,
    "sweep": _sweep,
    "verify": _verify,
    "add-experiments": _add_experiments,
    "compare": _compare,
    "scenarios": _scenarios,
    "cache": _cache,
}


def dispatch(args: argparse.Namespace) -> int:
    """Run the parsed subcommand; its exit code."""
    return COMMANDS[args.command](args)
