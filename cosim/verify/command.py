"""``glider-cosim verify`` (and ``python -m glider_cosim.verify``): its options and its run."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable

from ..fmus.options import add_overwrite_option
from ..inputs.text import one_line, quote
from .cases import COMPONENTS, VerifyInputError, kit_root


def add_arguments(p: argparse.ArgumentParser, tolerance: Callable[[str], float]) -> None:
    """The options of ``glider-cosim verify`` (shared with ``python -m``)."""
    p.add_argument("fmu", nargs="?", default=None, help="the FMU to verify")
    p.add_argument(
        "--component",
        choices=tuple(COMPONENTS),
        default=None,
        help="plant, observer or controller (default: found from the variables)",
    )
    p.add_argument("--case", default=None, help="one case (default: every case)")
    p.add_argument(
        "--kit",
        action="store_true",
        help="run the verification kit's cases of our components instead of the FMI-LS-REF "
        "experiments the FMU carries (implied by --component, --case, --rtol, --atol)",
    )
    p.add_argument(
        "--rtol",
        type=tolerance,
        default=None,
        help="relative tolerance for every case (default: each case's)",
    )
    p.add_argument(
        "--atol",
        type=tolerance,
        default=None,
        help="absolute tolerance for every case, SI units (default: each case's)",
    )
    p.add_argument(
        "--json",
        action="store_true",
        help="print the whole result as one JSON object (for CI systems) instead of the table",
    )
    p.add_argument(
        "--write-references",
        action="store_true",
        help="rerun the cases on our FMUs and rewrite the shipped references",
    )
    p.add_argument(
        "--export",
        default=None,
        metavar="DIR",
        help="write the cases with our FMUs in the FMI Cross-Check layout",
    )
    p.add_argument(
        "--fmu-dir",
        default=None,
        help="our FMUs for --write-references/--export and the loop checks' closed loop, "
        "built if missing or stale "
        "(default: the per-user cache)",
    )
    add_overwrite_option(p)


def add_experiments_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``glider-cosim add-experiments``."""
    from ..fmus.lsref import ROLES

    p.description = (
        "Put FMU in the loop of a scenario (the instance its [fmus] table gives it, else\n"
        "the component whose interface it has), run the loop, and write a copy of FMU that\n"
        "carries an FMI-LS-REF experiment: its recorded inputs as stimuli, its outputs as\n"
        "references, the scenario's parameter values. FMU itself is never written over."
    )
    p.add_argument("fmu", metavar="FMU", help="your FMI 2.0 or 3.0 co-simulation FMU")
    p.add_argument("--from", dest="case", required=True, metavar="CASE",
                   help="a shipped scenario's name or a scenario file")  # fmt: skip
    p.add_argument("--out", required=True, metavar="NEW.fmu",
                   help="the new FMU (not FMU; an existing file only if glider-cosim "
                   "wrote it)")  # fmt: skip
    p.add_argument("--role", default=ROLES[0], choices=ROLES,
                   help="the experiment's role (default: experiment, a smoke test)")  # fmt: skip
    p.add_argument("--fmu-dir", default=None,
                   help="our other FMUs of the loop (default: the per-user cache)")  # fmt: skip


def run_command(args: argparse.Namespace) -> int:
    """``glider-cosim verify``: 0 if at least one case ran and every case run passed, 1 if
    a case failed; VerifyInputError (bad input, the core interface missing, no case could
    run) -> 2. With ``--json`` a refusal is printed as ``{"error": ..., "exit_code": 2}``
    too."""
    from .compare import verify
    from .writing import export, write_references

    if args.command == "add-experiments":
        from .lsref_add import add_experiments

        print(f"wrote {add_experiments(args.fmu, args.case, args.out, args.role, args.fmu_dir)}")
        return 0
    if args.write_references or args.export:
        if args.fmu is not None:
            raise VerifyInputError("give an FMU or --write-references/--export, not both")
        if args.overwrite_fmus and args.fmu_dir is not None:
            from ..fmus.folders import prepare_fmus

            prepare_fmus(args.fmu_dir, None, overwrite=True)  # then ours, current
        if args.write_references:
            files = write_references(args.fmu_dir)
            print(f"wrote {len(files)} files under {kit_root()}")
        if args.export:
            print(f"wrote {export(args.export, args.fmu_dir)}")
        return 0
    if args.fmu is None:
        raise VerifyInputError("expected an FMU (or --write-references, --export DIR)")
    kit = args.kit or args.component or args.case or args.rtol is not None or args.atol is not None
    try:
        if not kit:  # the experiments the FMU carries (FMI-LS-REF), else the kit's cases
            from .lsref import lsref_command

            code = lsref_command(args.fmu, args.json)
            if code is not None:
                return code
        report = verify(
            args.fmu, args.component, args.case, args.rtol, args.atol, fmu_dir=args.fmu_dir
        )
    except VerifyInputError as err:
        if args.json:
            print(json.dumps({"fmu": args.fmu, "passed": False, "exit_code": 2,
                              "error": one_line(err)}))  # fmt: skip
        raise
    print(json.dumps(report.as_dict(), indent=1) if args.json else report.table())
    return report.exit_code


def tolerance_arg(text: str) -> float:
    """An ``--rtol``/``--atol`` argument as a float (argparse's type)."""
    from .compare import check_tolerance

    try:
        value = check_tolerance(text, "")
    except VerifyInputError:
        raise argparse.ArgumentTypeError(
            f"{quote(text)} is invalid: expected a finite number >= 0"
        ) from None
    assert value is not None
    return value
