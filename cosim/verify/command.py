"""``glider-cosim verify`` (and ``python -m glider_cosim.verify``) as one call:
:func:`verify_command`, its keyword arguments named as the command's options."""

from __future__ import annotations

import json as json_
from pathlib import Path

from ..inputs.text import one_line
from .cases import VerifyInputError, kit_root


def verify_command(
    fmu: str | None = None,
    *,
    component: str | None = None,
    case: str | None = None,
    kit: bool = False,
    rtol: float | None = None,
    atol: float | None = None,
    json: bool = False,
    write_references: bool = False,
    export: str | None = None,
    fmu_dir: str | None = None,
    overwrite_fmus: bool = False,
) -> int:
    """Verify an FMU, or rewrite/export the kit's references; print the result.

    Parameters
    ----------
    fmu : str, optional
        The FMU to verify: the FMI-LS-REF experiments it carries, else (or with ``kit``,
        implied by ``component``, ``case``, ``rtol``, ``atol``) the kit's cases.
    component : {"plant", "observer", "controller"}, optional
        Default: found from the FMU's variables.
    case : str, optional
        One case (default: every case).
    kit : bool
        The kit's cases instead of the FMU's own experiments.
    rtol, atol : float, optional
        Relative and absolute (SI units) tolerances for every case (default: each case's).
    json : bool
        Print the whole result as one JSON object instead of the table; a refusal too
        (``{"error": ..., "exit_code": 2}``).
    write_references : bool
        Rerun the cases on our FMUs and rewrite the shipped references.
    export : str, optional
        A folder (checked first): the cases with our FMUs in the FMI Cross-Check layout.
    fmu_dir : str, optional
        Our FMUs for ``write_references``/``export`` and the loop checks' closed loop
        (default: the per-user cache).
    overwrite_fmus : bool
        Replace what ``fmu_dir`` holds under our FMUs' names.

    Returns
    -------
    int
        0 if at least one case ran and every case run passed, 1 if a case failed.

    Raises
    ------
    VerifyInputError
        Bad input, the core interface missing, no case could run (exit code 2).
    """
    from .compare import verify
    from .writing import export as export_cases
    from .writing import write_references as write

    if export:
        from ..inputs.outputs import check_out_dir

        check_out_dir(Path(export), "--export")
    if write_references or export:
        if fmu is not None:
            raise VerifyInputError("give an FMU or --write-references/--export, not both")
        if overwrite_fmus and fmu_dir is not None:
            from ..fmus.folders import prepare_fmus

            prepare_fmus(fmu_dir, None, overwrite=True)  # then ours, current
        if write_references:
            files = write(fmu_dir)
            print(f"wrote {len(files)} files under {kit_root()}")
        if export:
            print(f"wrote {export_cases(export, fmu_dir)}")
        return 0
    if fmu is None:
        raise VerifyInputError("expected an FMU (or --write-references, --export DIR)")
    kit = kit or bool(component or case) or rtol is not None or atol is not None
    try:
        if not kit:  # the experiments the FMU carries (FMI-LS-REF), else the kit's cases
            from .lsref import lsref_command

            code = lsref_command(fmu, json)
            if code is not None:
                return code
        report = verify(fmu, component, case, rtol, atol, fmu_dir=fmu_dir)
    except VerifyInputError as err:
        if json:
            print(json_.dumps({"fmu": fmu, "passed": False, "exit_code": 2,
                               "error": one_line(err)}))  # fmt: skip
        raise
    print(json_.dumps(report.as_dict(), indent=1) if json else report.table())
    return report.exit_code
