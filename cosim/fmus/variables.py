"""What a model's variables are, asked of its model description: their start values
(:func:`parameter_defaults`), their units, and a value in words with its unit
(:func:`with_unit`: the one rule behind the run's echo of its overrides, the plots'
subtitles and event labels, and the sweep's axes).

A unit comes from a model description when one is given (the run's own FMUs, which may
be another tool's), else from our FMUs' variable tables (a figure drawn from a results
folder, a sweep's axis).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..components import COMPONENTS
from ..inputs.check import our_table
from ..inputs.values import has_unit, is_angle, unit_of

__all__ = ["LAW_NAMES", "LOOP_INTERFACE", "overrides_echo", "overrides_words",
           "parameter_defaults", "plain", "short", "unit_of_target", "with_unit"]  # fmt: skip

#: ``controller.law``'s codes and their names
LAW_NAMES = {0: "open-loop", 1: "passivity", 2: "p", 3: "pi"}


#: what the closed loop needs of an FMU swapped in for our controller or estimator, from
#: each component's ``component.toml`` ``[interface]`` (:mod:`glider_cosim.components`):
#: component -> variable -> (causality, unit, when it is needed). ``"required"``: the
#: loop refuses an FMU without it; ``"optional"``: connected when the FMU declares it,
#: else skipped with a one-line note; ``"read"``: required when the other component in the
#: loop reads it (our controller reads ``V_hat``). Any other input is connected to the
#: loop's output of the same name if there is one. ``docs/reference/fmu-interfaces.md``
#: and the how-to pages show this table (the controller first: the one swapped most).
LOOP_INTERFACE: dict[str, dict[str, tuple[str, str, str]]] = {
    c.name: c.interface for c in sorted(COMPONENTS, key=lambda c: c.estimator) if c.interface
}


def parameter_defaults(fmu: str | Path) -> dict[str, Any]:
    """Start values of an FMU's parameters and inputs, by name, from its model
    description (Real as float, Integer as int, Boolean as bool), read by fmpy
    (:func:`glider_cosim.inputs.archives.read_description`)."""
    from ..inputs.archives import read_description

    conv = {"Real": float, "Integer": int, "Boolean": lambda v: str(v).lower() in ("true", "1")}
    md = read_description(fmu)
    return {
        v.name: conv[v.type](v.start)
        for v in md.modelVariables
        if v.causality in ("parameter", "input") and v.type in conv
    }


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
    md : ModelDescription, optional
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


def overrides_echo(overrides: dict[str, Any], fmus: dict[str, Any]) -> str:
    """Every override with the unit of its variable, an angle in rad in degrees too (one
    given in degrees in rad too): ``"controller.K_c = 6, plant.alpha_0 = 1 rad (57.3
    deg), plant.V_0 = 0.2 m/s"`` ("" if none).

    Parameters
    ----------
    overrides : dict
        ``instance.variable`` -> value as given (a number, or a ``"X deg"`` / ``"0.2 m/s"``
        :class:`~glider_cosim.inputs.values.Quantity`): a scenario's ``overrides``.
    fmus : dict
        Instance -> its FMU file: the units come from its model description (one that
        cannot be read: from our FMUs' tables), in words by
        :func:`~glider_cosim.fmus.variables.with_unit`.
    """
    from ..inputs.archives import InputFileError, read_description

    descriptions: dict[str, Any] = {}
    for inst in {ref.partition(".")[0] for ref in overrides}:
        try:
            descriptions[inst] = read_description(fmus[inst])
        except (InputFileError, KeyError, TypeError, AttributeError):  # our tables then
            descriptions[inst] = None
    return ", ".join(
        f"{ref} = {with_unit(ref, value, descriptions[ref.partition('.')[0]], both=True)}"
        for ref, value in overrides.items()
    )
