"""A value of one of a model's variables in words, with its unit: the one rule behind the
run's echo of its overrides, the plots' subtitles and event labels, and the sweep's axes.

The unit comes from a model description when one is given (the run's own FMUs, which
may be another tool's), else from our FMUs' variable tables (a figure drawn from a
results folder, a sweep's axis).
"""

from __future__ import annotations

import math
from typing import Any

from ..inputs.check import our_table
from ..inputs.values import has_unit, is_angle, unit_of

__all__ = ["LAW_NAMES", "overrides_words", "plain", "short", "unit_of_target", "with_unit"]

#: ``controller.law``'s codes and their names
LAW_NAMES = {0: "open-loop", 1: "passivity", 2: "p", 3: "pi"}


def plain(value: Any) -> Any:
    """A value for JSON: a ``"X deg"`` angle keeps its text, floats stay floats."""
    text = getattr(value, "text", None)
    if isinstance(text, str):
        return text
    if isinstance(value, bool | int | float | str) or value is None:
        return value
    try:
        return float(value)
    except (TypeError, ValueError):
        return str(value)


def short(value: Any) -> str:
    """``value`` in its shortest words: a float as ``%g``, ``"-30 deg"`` as written."""
    value = plain(value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def _variable(target: str, md: Any) -> tuple[str | None, bool]:
    """The unit of ``instance.name`` (``"1"``: none; None: no such variable) and whether
    it is an angle in rad, from ``md`` or, without one, our FMUs' tables."""
    inst, _, name = target.partition(".")
    if md is None:
        try:
            unit = our_table(inst)[name].unit or "1"
        except KeyError:
            return None, False
        return unit, unit == "rad"
    var = next((v for v in md.modelVariables if v.name == name), None)
    if var is None:
        return None, False
    return (unit_of(var) if has_unit(var) else "1"), is_angle(md, var)


def unit_of_target(target: str, md: Any = None) -> str | None:
    """The unit of ``instance.name`` (``"1"``: none), for labels; None for a variable
    that is not in ``md`` (without ``md``: not one of our FMUs')."""
    return _variable(target, md)[0]


def with_unit(target: str, value: Any, md: Any = None, *, both: bool = False) -> str:
    """``value`` of variable ``target`` in words: a number followed by its unit
    (``0.3 m/s``), a value written with a unit (``-30 deg``) as given, ``controller.law``
    by name.

    Parameters
    ----------
    target : str
        ``instance.name``.
    value : number, str or Quantity
        As given (``6``, ``"-30 deg"`` parsed into a :class:`~glider_cosim.inputs.values.Degrees`).
    md : fmpy ModelDescription, optional
        Where the unit comes from; without it, our FMUs' tables.
    both : bool
        Also the other form in parentheses: an angle in rad in degrees and one given in
        degrees in rad (``1 rad (57.3 deg)``), a law's code with its name (``1 (passivity)``).
    """
    from ..inputs.values import Degrees, Quantity

    if isinstance(value, Degrees) and both:
        return f"{value.text} ({float(value):.4g} rad)"
    if isinstance(value, Quantity):
        return value.text
    if target == "controller.law" and value in LAW_NAMES:
        return f"{value} ({LAW_NAMES[value]})" if both else LAW_NAMES[value]
    text = short(value)
    unit, angle = _variable(target, md)
    if unit in (None, "1") or isinstance(value, bool) or not isinstance(plain(value), int | float):
        return text
    if both and angle:
        return f"{text} {unit} ({math.degrees(value):.4g} deg)"
    return f"{text} {unit}"


def overrides_words(overrides: dict[str, Any], units: bool = False) -> list[str]:
    """``instance.name=value`` of each override (``controller.law`` by name); ``units``:
    each number with its unit (:func:`with_unit`, from our FMUs' tables)."""
    return [
        f"{k}={with_unit(k, v) if units or k == 'controller.law' else short(v)}"
        for k, v in overrides.items()
    ]
