"""The component verification kit: reference cases run on any FMU of a component.

``glider-cosim verify`` and :func:`glider_cosim.testing.assert_matches_reference` are
its front ends; ``python -m glider_cosim.verify --write`` regenerates the references.
"""

from .cases import (
    COMPONENTS,
    CaseFileError,
    VerifyInputError,
    case_names,
    kit_files,
    kit_root,
    load_case,
)
from .compare import CaseResult, Report, verify
from .run import RUNNERS
from .writing import export, write_references

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
