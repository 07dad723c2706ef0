"""The component verification kit: reference cases run on any FMU of a component.

``glider-cosim verify`` and :func:`glider_cosim.testing.assert_matches_reference` are
its front ends; ``python -m glider_cosim.verify --write`` regenerates the references.
"""

from glider_cosim.verify.compare import (
    COMPONENTS,
    RUNNERS,
    CaseFileError,
    CaseResult,
    Report,
    VerifyInputError,
    case_names,
    export,
    kit_files,
    kit_root,
    load_case,
    verify,
    write_references,
)

__all__ = [
    "COMPONENTS",
    "RUNNERS",
    "CaseFileError",
    "CaseResult",
    "Report",
    "VerifyInputError",
    "case_names",
    "export",
    "kit_files",
    "kit_root",
    "load_case",
    "verify",
    "write_references",
]
