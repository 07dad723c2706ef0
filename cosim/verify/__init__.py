"""The component verification kit: reference cases run on any FMU of a component.

``glider-cosim verify`` and :func:`glider_cosim.testing.assert_matches_reference` are
its front ends; ``python -m glider_cosim.verify --write`` regenerates the references.
Each name is imported on first use (the command line's parser imports :mod:`.cases` alone).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..inputs.lazy import lazy_names

if TYPE_CHECKING:
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
_HOMES = {"cases": ("COMPONENTS", "CaseFileError", "VerifyInputError", "case_names", "kit_files",
                    "kit_root", "load_case"),
          "compare": ("CaseResult", "Report", "verify"), "run": ("RUNNERS",),
          "writing": ("export", "write_references")}  # fmt: skip
__getattr__, __dir__ = lazy_names(
    __name__, {name: module for module, names in _HOMES.items() for name in names}
)
