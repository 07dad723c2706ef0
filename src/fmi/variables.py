"""An FMU variable of our slaves (:class:`Var`) and what its valid range offers: the
tables of ``glider_<component>.variables`` are made of them, without pythonfmu."""

from __future__ import annotations

from typing import NamedTuple, Protocol


class ValidRange(Protocol):
    """What a variable's valid range offers (e.g. ``glider_plant.params.Range``)."""

    def contains(self, value: float) -> bool: ...

    def describe(self, integer: bool = False) -> str: ...


class Var(NamedTuple):
    """One FMU variable: name, causality, unit, description, start, type, variability."""

    name: str
    causality: str  # "input" | "output" | "parameter" | "local" (a state derivative)
    unit: str
    description: str
    start: float = 0.0
    type: str = "Real"  # "Real" | "Integer" | "Boolean"
    tunable: bool = False
    valid: ValidRange | None = None  # checked before the first step (parameters, inputs)
