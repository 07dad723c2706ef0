"""Values checked against a variable's FMI type and unit.

Integers are taken exactly (no truncation, no wrapping: FMI 2.0 Integer is 32-bit),
booleans are not numbers. A value written with a unit (a :class:`Quantity`, parsed by
:func:`parse_quantity` for ``--set``, scenario files and sweep specs alike) is accepted
only in the variable's own declared unit (``"0.2 m/s"`` for ``plant.V_0``), or as
``"X deg"`` (a :class:`Degrees`) for an angle (unit ``rad``); every unit is refused on a
variable that declares none (:func:`check_unit`).
"""

from __future__ import annotations

import math
import re
from typing import Any

from .text import quote

INT_MIN, INT_MAX = -(2**31), 2**31 - 1
_BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
#: a number and a unit: ``"0.2 m/s"``, ``"-30 deg"``, ``"10Hz"`` (a unit that starts with
#: a digit, e.g. ``1/s``, needs the space; ``1e-3`` is a number, not 1 in "e-3")
_QUANTITY = re.compile(rf"^\s*({_NUMBER})(?![eE][-+]?\d)(?:\s*([A-Za-z%][^\s]*)|\s+([^\s]+))\s*$")


class Quantity(float):
    """A number written with a unit, e.g. ``"0.2 m/s"``.

    The float is the number in ``unit`` (for :class:`Degrees`, in rad), ``text`` the input
    as written, ``unit`` the unit written; :func:`check_unit` decides whether the
    variable it is meant for accepts that unit.
    """

    text: str
    unit: str

    def __new__(cls, value: float, text: str, unit: str) -> Quantity:
        obj = super().__new__(cls, value)
        obj.text = text
        obj.unit = unit
        return obj

    def __reduce__(self) -> tuple:
        return (Quantity, (float(self), self.text, self.unit))

    def __deepcopy__(self, memo: dict) -> Quantity:
        return self


class Degrees(Quantity):
    """An angle given as ``"X deg"``: the float is its value in rad, ``text`` the input."""

    def __new__(cls, radians: float, text: str) -> Degrees:
        return super().__new__(cls, radians, text, "deg")

    def __reduce__(self) -> tuple:
        return (Degrees, (float(self), self.text))


def parse_quantity(text: str) -> Quantity | None:
    """``"0.2 m/s"`` -> ``Quantity(0.2, unit="m/s")``, ``"-30 deg"`` -> :class:`Degrees`
    (in rad); ``None`` if ``text`` is not a finite number followed by a unit.

    The one reading of a value with a unit, for ``--set``, scenario files and sweep
    specs; whether the unit fits the variable is :func:`check_unit`'s decision.
    """
    m = _QUANTITY.match(text) if isinstance(text, str) and len(text) < 1000 else None
    if not m:
        return None
    number, unit = float(m.group(1)), m.group(2) or m.group(3)
    if unit == "deg":
        number = math.radians(number)
    if not math.isfinite(number):
        return None
    shown = text.strip()
    return Degrees(number, shown) if unit == "deg" else Quantity(number, shown, unit)


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
    """True if ``var`` (a model variable, ours or fmpy's) declares a unit (itself or its type)."""
    return bool(var.unit or (var.declaredType.unit if var.declaredType is not None else None))


def unit_of(var: Any) -> str:
    """The unit of ``var`` for messages (``"1"`` if none)."""
    unit = var.unit or (var.declaredType.unit if var.declaredType is not None else None)
    return unit or "1"


def _expected(unit: str | None, angle: bool) -> str:
    if unit is None:
        return "a plain number"
    return f"a number in {unit}" + (" or 'X deg'" if angle else "")


def expected_unit(md: Any, var: Any) -> str:
    """What a value for ``var`` may be written as, for messages: ``"a number in m/s"``,
    ``"a number in rad or 'X deg'"``, ``"a plain number"`` (no unit declared)."""
    return _expected(unit_of(var) if has_unit(var) else None, is_angle(md, var))


def check_unit(value: Any, md: Any, var: Any, where: str) -> None:
    """Refuse a :class:`Quantity` whose unit ``var`` (of model description ``md``) does
    not take.

    Accepted: the variable's declared unit (``"0.2 m/s"`` for a variable in ``m/s``) and
    ``deg`` for an angle (``rad``). Refused, naming what is expected: any other unit, and
    every unit on a variable that declares none. A plain number always passes.

    Raises
    ------
    ValueCheckError
        ``where: 'TEXT' is invalid: NAME is in UNIT: expected ...`` (or ``NAME has no
        unit``).
    """
    unit = unit_of(var) if has_unit(var) else None
    check_declared_unit(value, var.name, unit, where, angle=is_angle(md, var))


def check_declared_unit(
    value: Any, name: str, unit: str | None, where: str, angle: bool | None = None
) -> None:
    """:func:`check_unit` for a variable known by its unit only (``None`` or ``"1"``: it
    declares none; ``angle`` defaults to ``unit == "rad"``), e.g. from our FMUs'
    variable tables before any FMU is built."""
    if not isinstance(value, Quantity):
        return
    unit = None if unit in (None, "", "1") else unit
    angle = unit == "rad" if angle is None else angle
    if (value.unit == "deg" and angle) or (value.unit != "deg" and value.unit == unit):
        return
    what = f"{name} is in {unit}" if unit is not None else f"{name} has no unit"
    raise ValueCheckError(
        f"{where}: {quote(value.text)} is invalid: {what}: expected {_expected(unit, angle)}"
    )


def check_value(value: Any, md: Any, var: Any, where: str) -> float | int | bool:
    """``value`` converted for ``var`` (a model variable, ours or fmpy's), or
    :class:`ValueCheckError` naming ``where``, the value and what was expected.

    Real: a finite int or float (a :class:`Quantity` in the units :func:`check_unit`
    accepts); Integer: an exact integer in [-2**31, 2**31 - 1] (an integral float such
    as ``3.0`` is taken; a unit only if it is the declared one); Boolean: true or false.
    """
    text = value.text if isinstance(value, Quantity) else value
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
        if isinstance(value, Quantity):
            if not has_unit(var) or value.unit != unit_of(var):
                raise ValueCheckError(
                    f"{where}: {shown} is invalid: expected an integer without a unit"
                )
            value = float(value)
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
        check_unit(value, md, var, where)
        try:
            v = float(value)
        except OverflowError:
            v = math.inf
        if not math.isfinite(v):
            raise ValueCheckError(f"{where}: {shown} is invalid: expected a finite number")
        _check_bounds(v, var, where, shown)
        return value if isinstance(value, Quantity) else v
    raise ValueCheckError(f"{where}: {var.name} has type {var.type}, which cannot be set")
