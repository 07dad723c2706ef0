"""Quantity labels without a unit (issue 45, item 9): the rule the figures' test holds
every label to.

- An axis label names its unit in brackets: ``time [s]``, ``K_c [1]`` (``[1]``: a
  quantity without dimension, as the FMUs' model descriptions write it).
- A value quoted in a title, legend entry or note (``NAME = 0.1``, ``t = 5 s``,
  ``plant.z >= 1``) is followed by its unit, unless NAME is a variable of our FMUs that
  has none (``K_c = 2``: its unit is ``1``).
"""

from __future__ import annotations

import re

from glider_cosim.inputs.check import our_table

#: the units a figure may quote after a value
UNITS = {"s", "ms", "deg", "rad", "rad^2", "rad2", "m", "m/s", "Hz", "%", "kg", "N", "1"}

#: ``NAME = 0.1``, ``NAME >= 1``, ``NAME=0.1`` with what follows the number
_QUANTITY = re.compile(r"(?<![\w.])([A-Za-z][\w.]*)\s*(?:=|>=|<=|>|<)\s*"
                       r"([-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?)(?![\d.])([^,;)\n]*)")  # fmt: skip


def dimensionless() -> set[str]:
    """Names (bare and ``instance.name``) of our FMUs' variables whose unit is ``1``."""
    out = set()
    for inst in ("plant", "observer", "controller"):
        for name, var in our_table(inst).items():
            if var.unit == "1":
                out |= {name, f"{inst}.{name}"}
    return out


def axis_label_problem(label: str) -> str | None:
    """Why an axis label has no unit, or None."""
    if not label.strip():
        return None
    m = re.search(r"\[([^\]]+)\]", label)
    if m is None:
        return f"axis label {label!r}: no [unit]"
    return None


def quantity_problems(text: str, plain: set[str]) -> list[str]:
    """Each ``NAME = value`` of ``text`` without a unit after the value (``plain``: the
    names that have none)."""
    out = []
    for name, value, rest in _QUANTITY.findall(text):
        unit = rest.strip().split(" ")[0] if rest.strip() else ""
        if unit in UNITS or name in plain:
            continue
        out.append(f"{text!r}: {name} = {value} has no unit")
    return out
