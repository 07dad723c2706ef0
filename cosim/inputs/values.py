"""Values checked against a variable's FMI type and unit.

Integers are taken exactly (no truncation, no wrapping: FMI 2.0 Integer is 32-bit),
booleans are not numbers, and an angle written ``"X deg"`` (a :class:`Degrees`) is
accepted only by a Real variable whose unit is an angle (``rad``), or that declares no
unit at all (a foreign FMU without units).
"""

from __future__ import annotations

import math
from typing import Any

from .text import quote

INT_MIN, INT_MAX = -(2**31), 2**31 - 1
_BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


class Degrees(float):
    """An angle given as ``"X deg"``: the float is its value in rad, ``text`` the input."""

    text: str

    def __new__(cls, radians: float, text: str) -> Degrees:
        obj = super().__new__(cls, radians)
        obj.text = text
        return obj

    def __reduce__(self) -> tuple:
        return (Degrees, (float(self), self.text))

    def __deepcopy__(self, memo: dict) -> Degrees:
        return self


class ValueCheckError(ValueError):
    """A value does not fit its variable (type, integer range, unit, finiteness)."""


def is_angle(md: Any, var: Any) -> bool:
    """True if the Real variable ``var`` of model description ``md`` is an angle in rad."""
    unit = var.unit or (var.declaredType.unit if var.declaredType is not None else None)
    if unit is None:
        return False
    if unit == "rad":
        return True
    for u in md.unitDefinitions or ():
        if u.name == unit and u.baseUnit is not None:
            b = u.baseUnit
            dims = {k: getattr(b, k, 0) or 0 for k in _BASE}
            return (
                dims.pop("rad") == 1
                and not any(dims.values())
                and float(b.factor or 1.0) == 1.0
                and float(b.offset or 0.0) == 0.0
            )
    return False


def _bound(text: Any) -> float | None:
    try:
        b = float(text)
    except (TypeError, ValueError):
        return None
    return b if math.isfinite(b) else None


def _check_bounds(value: float, var: Any, where: str, shown: str) -> None:
    """The model description's ``min``/``max`` of ``var``, if it declares them."""
    lo, hi = _bound(getattr(var, "min", None)), _bound(getattr(var, "max", None))
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        lo_s = "-inf" if lo is None else f"{lo:g}"
        hi_s = "inf" if hi is None else f"{hi:g}"
        raise ValueCheckError(
            f"{where}: {shown} is invalid: expected a value in [{lo_s}, {hi_s}] "
            f"({var.name}'s min and max in its model description)"
        )


def has_unit(var: Any) -> bool:
    return bool(var.unit or (var.declaredType.unit if var.declaredType is not None else None))


def unit_of(var: Any) -> str:
    """The unit of ``var`` for messages (``"1"`` if none)."""
    unit = var.unit or (var.declaredType.unit if var.declaredType is not None else None)
    return unit or "1"


def check_value(value: Any, md: Any, var: Any, where: str) -> float | int | bool:
    """``value`` converted for ``var`` (a ``fmpy`` ScalarVariable), or
    :class:`ValueCheckError` naming ``where``, the value and what was expected.

    Real: a finite int or float (``"X deg"`` only if the unit is an angle); Integer: an
    exact integer in [-2**31, 2**31 - 1] (an integral float such as ``3.0`` is taken);
    Boolean: true or false.
    """
    text = value.text if isinstance(value, Degrees) else value
    shown = quote(text)
    if var.type == "Boolean":
        if not isinstance(value, bool):
            raise ValueCheckError(f"{where}: {shown} is invalid: expected true or false")
        return value
    if isinstance(value, bool):
        raise ValueCheckError(
            f"{where}: {shown} is invalid: expected a number ({var.type}), not a boolean"
        )
    if var.type == "Integer":
        if isinstance(value, Degrees):
            raise ValueCheckError(
                f"{where}: {shown} is invalid: expected an integer without a unit"
            )
        if isinstance(value, float):
            if not (math.isfinite(value) and value.is_integer()):
                raise ValueCheckError(f"{where}: {shown} is invalid: expected an integer")
            value = int(value)
        if not isinstance(value, int):
            raise ValueCheckError(f"{where}: {shown} is invalid: expected an integer")
        if not INT_MIN <= value <= INT_MAX:
            raise ValueCheckError(
                f"{where}: {shown} is invalid: expected an integer in [{INT_MIN}, {INT_MAX}]"
            )
        _check_bounds(value, var, where, shown)
        return value
    if var.type == "Real":
        if not isinstance(value, int | float):
            raise ValueCheckError(f"{where}: {shown} is invalid: expected a number")
        if isinstance(value, Degrees) and has_unit(var) and not is_angle(md, var):
            raise ValueCheckError(
                f"{where}: {shown} is invalid: 'deg' only applies to angles; "
                f"{var.name} is in {unit_of(var)}"
            )
        try:
            v = float(value)
        except OverflowError:
            v = math.inf
        if not math.isfinite(v):
            raise ValueCheckError(f"{where}: {shown} is invalid: expected a finite number")
        _check_bounds(v, var, where, shown)
        return value if isinstance(value, Degrees) else v
    raise ValueCheckError(f"{where}: {var.name} has type {var.type}, which cannot be set")
