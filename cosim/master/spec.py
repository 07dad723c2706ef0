"""The description of a system to co-simulate: FMUs, wiring, driven inputs, events, steps."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from ..inputs.text import quote
from .errors import SystemSpecError

COUPLINGS = ("gauss-seidel", "jacobi")
#: default limit of communication steps in one run (``--max-steps``)
DEFAULT_MAX_STEPS = 1_000_000


#: :meth:`VarRef.parse`'s references, by text
_PARSED: dict[str, VarRef] = {}


@dataclass(frozen=True)
class VarRef:
    """``instance.variable``."""

    instance: str
    variable: str

    @classmethod
    def parse(cls, text: str) -> VarRef:
        """``"instance.variable"`` as a reference (the same object for the same text: a
        sweep's worker resolves its parameters' names at every run)."""
        known = _PARSED.get(text) if cls is VarRef and isinstance(text, str) else None
        if known is not None:
            return known
        inst, sep, var = text.partition(".")
        if not sep or not inst or not var:
            raise SystemSpecError(
                f"{quote(text)} is not a variable reference: expected instance.variable"
            )
        ref = cls(inst, var)
        if cls is VarRef and len(_PARSED) < 10_000:
            _PARSED[text] = ref
        return ref

    def __str__(self) -> str:
        return f"{self.instance}.{self.variable}"


@dataclass
class Event:
    """Set variables once a condition first holds at a communication point.

    ``variable`` is ``"time"`` or ``instance.variable`` (an output); the condition is
    ``value >= threshold`` (``op=">="``) or ``value <= threshold``. Actions are applied
    ``delay`` seconds after the condition first holds.
    """

    variable: str
    op: str
    threshold: float
    actions: dict[str, float | int | bool]
    delay: float = 0.0
    fired_at: float | None = None
    applied: bool = False

    def holds(self, value: float) -> bool:
        return value >= self.threshold if self.op == ">=" else value <= self.threshold


@dataclass
class Disturbance:
    """A step (from ``time`` on) or pulse (``time`` to ``time + duration``) on an input."""

    target: str
    kind: str
    time: float
    value: float
    duration: float = 0.0

    def at(self, t: float) -> float:
        eps = 1e-9
        if t < self.time - eps:
            return 0.0
        if self.kind == "pulse" and t >= self.time + self.duration - eps:
            return 0.0
        return self.value


@dataclass
class System:
    """FMUs under instance names, parameters, connections and driven inputs."""

    fmus: dict[str, Path]
    connections: list[tuple[str, str]]
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: inputs the master drives (constant base value, plus disturbances)
    driven: dict[str, float] = field(default_factory=dict)
    disturbances: list[Disturbance] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)
    #: inputs driven by a table (times in s, values), held from each time to the next
    tables: dict[str, tuple[Sequence[float], Sequence[float]]] = field(default_factory=dict)
    #: variables recorded; None = every output of every instance
    record: list[str] | None = None


class Recorder(Protocol):
    """Receives the column names once, then one row per communication point."""

    def start(self, columns: Sequence[str]) -> None: ...

    def row(self, values: Sequence[float]) -> None: ...

    def close(self) -> None: ...


def count_steps(span: float, step: float, max_steps: int = DEFAULT_MAX_STEPS) -> int:
    """Number of communication steps of ``step`` s in ``span`` s.

    Raises
    ------
    SystemSpecError
        ``span`` or ``step`` not finite and > 0, ``step`` larger than ``span``, ``span``
        not a whole number of steps (to 1e-6 of a step), or more than ``max_steps``.
    """
    if not (isinstance(span, int | float) and math.isfinite(span) and span > 0):
        raise SystemSpecError(
            f"stop time {quote(span)} s is invalid: expected a finite value > the start time"
        )
    if not (isinstance(step, int | float) and math.isfinite(step) and step > 0):
        raise SystemSpecError(f"step = {quote(step)} s is invalid: expected a finite value > 0")
    ratio = span / step
    if not math.isfinite(ratio) or ratio > max_steps + 0.5:
        raise SystemSpecError(
            f"step {step:.6g} s over {span:.6g} s is {ratio:.3g} steps: more than the limit "
            f"of {max_steps} (option --max-steps)"
        )
    if ratio < 1 - 1e-6:
        raise SystemSpecError(f"step {step:.6g} s is longer than the run ({span:.6g} s)")
    n = round(ratio)
    if abs(ratio - n) > 1e-6:
        raise SystemSpecError(
            f"the run ({span:.6g} s) is not a whole number of steps of {step:.6g} s "
            f"({ratio:.6g} steps)"
        )
    return n
