"""The glider's model constants as FMU parameters, shared by the three slaves."""

from __future__ import annotations

from glider_fmi.variables import Var

from .params import MODEL_CONSTANTS


def model_constant_vars() -> tuple[Var, ...]:
    """The model constants as fixed parameters (single source: ``MODEL_CONSTANTS``)."""
    return tuple(
        Var(s.name, "parameter", s.unit, s.description, s.default, valid=s.valid)
        for s in MODEL_CONSTANTS
    )
