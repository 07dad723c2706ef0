"""Reading one value of a scenario: numbers, ``'X deg'``, enumerations, tables; the error raised."""

from __future__ import annotations

import math
import re
from typing import Any

from ..inputs.text import did_you_mean, quote
from ..inputs.values import Quantity, parse_quantity

LAWS = {"open-loop": 0, "passivity": 1, "p": 2, "pi": 3}


class ScenarioError(ValueError):
    """A scenario file is malformed; the message names the file and the key."""


def parse_number(value: Any, where: str, ref: str | None = None) -> float | int | bool:
    """A TOML value as a number; ``"NUMBER UNIT"`` becomes a
    :class:`~glider_cosim.inputs.values.Quantity` (``"X deg"`` a
    :class:`~glider_cosim.inputs.values.Degrees`, in rad).

    Types are kept (an int stays an int, a boolean a boolean): the variable's type and
    unit are checked against its FMU before the run
    (:func:`glider_cosim.inputs.values.check_unit`). ``ref`` (``instance.variable``)
    selects the unit hint of the message.
    """
    if isinstance(value, bool | int | float):
        return value
    if isinstance(value, str):
        q = parse_quantity(value)
        if q is not None:
            return q
    raise ScenarioError(f"{where}: {quote(value)} is not a number: expected {_expect_number(ref)}")


def _expect_number(ref: str | None) -> str:
    """What a number for ``instance.variable`` ``ref`` looks like: its unit from our FMUs'
    variable tables, and ``'X deg'`` only for an angle (rad). A variable we do not know
    (a swapped FMU's, a time) gets no unit hint."""
    unit = _our_unit(ref) if ref else None
    if unit == "rad":
        return "a number (rad) or 'X deg'"
    if unit and unit != "1":
        return f"a number ({unit}) or 'X {unit}'"
    return "a number"


def _our_unit(ref: str) -> str | None:
    inst, _, name = ref.partition(".")
    try:
        from ..inputs.check import our_table

        spec = our_table(inst).get(name)
    except (KeyError, ImportError):
        return None
    return None if spec is None else spec.unit


def parse_float(
    value: Any,
    where: str,
    positive: bool = False,
    non_negative: bool = False,
    angle: bool = False,
) -> float:
    """A finite float (``angle``: a value for a variable, so a unit such as ``"X deg"``
    is accepted here and checked against the variable's unit later)."""
    v = parse_number(value, where)
    if isinstance(v, Quantity) and not angle:
        raise ScenarioError(f"{where}: {quote(value)} is invalid: expected a number without a unit")
    try:
        finite = not isinstance(v, bool) and math.isfinite(float(v))
    except OverflowError:
        finite = False
    if not finite:
        raise ScenarioError(f"{where}: {quote(value)} is invalid: expected a finite number")
    if positive and not v > 0:
        raise ScenarioError(f"{where}: {quote(value)} is invalid: expected a number > 0")
    if non_negative and v < 0:
        raise ScenarioError(f"{where}: {quote(value)} is invalid: expected a number >= 0")
    return v if isinstance(v, Quantity) else float(v)


def _choices(names: Any) -> str:
    names = [f"'{n}'" for n in names]
    return " or ".join(names) if len(names) == 2 else ", ".join(names[:-1]) + " or " + names[-1]


#: what ``controller.law`` accepts, for messages
LAW_CHOICES = f"one of {', '.join(repr(n) for n in LAWS)} (any case) or an integer 0..3"


def parse_law(value: Any, where: str) -> Any:
    """``controller.law``: a name (any case) or an exact integer 0..3."""
    if isinstance(value, str):
        key = value.strip().lower()
        if key in LAWS:
            return LAWS[key]
        if re.fullmatch(r"[-+]?\d{1,3}", key) and int(key) in LAWS.values():
            return int(key)
    elif not isinstance(value, bool) and isinstance(value, int) and value in LAWS.values():
        return value
    raise ScenarioError(
        f"{where}: {quote(value)} is invalid: expected {LAW_CHOICES}" + did_you_mean(value, LAWS)
    )


def parse_choice(value: Any, choices: tuple[str, ...], where: str) -> str:
    """An enumerated string option (``coupling``, ``feedback``), any case."""
    if isinstance(value, str) and value.strip().lower() in choices:
        return value.strip().lower()
    raise ScenarioError(
        f"{where}: {quote(value)} is invalid: expected {_choices(choices)} (any case)"
        + did_you_mean(value, choices)
    )


def parse_table(value: Any, where: str) -> dict[str, Any]:
    """A scenario value that must be a TOML table."""
    if not isinstance(value, dict):
        raise ScenarioError(f"{where}: expected a table, got {type(value).__name__}")
    return value
