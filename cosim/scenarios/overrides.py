"""Overrides of a scenario: ``--set INSTANCE.NAME=VALUE`` and the report's and sweeps' variants."""

from __future__ import annotations

import copy
import re
from typing import Any

from ..inputs.text import quote
from .fields import LAWS, ScenarioError, parse_law, parse_number
from .scenario import INSTANCES, Scenario


def apply_overrides(sc: Scenario, overrides: dict[str, Any]) -> Scenario:
    """A copy of ``sc`` with ``instance.parameter`` overrides; ``event.instance.var``
    changes what the scenario's events set (e.g. which law takes over)."""
    sc = copy.deepcopy(sc)
    sc.overrides.update(overrides)
    for key, value in overrides.items():
        if key.startswith("event."):
            target = key.removeprefix("event.")
            if target == "controller.law" and isinstance(value, str):
                value = LAWS[value]
            for ev in sc.events:
                if target in ev.actions:
                    ev.actions[target] = value
            continue
        inst, _, name = key.partition(".")
        sc.parameters.setdefault(inst, {})[name] = value
    return sc


def parse_sets(items: list[str], source: str = "--set") -> dict[str, float | int | bool]:
    """``["controller.K_c=6", "plant.theta_g_0=-30 deg"]`` -> overrides (angles in rad)."""
    out: dict[str, float | int | bool] = {}
    for item in items:
        key, sep, text = item.partition("=")
        inst, dot, name = key.strip().partition(".")
        where = f"{source} {quote(item)}"
        if not sep or not dot or inst not in INSTANCES or not name:
            raise ScenarioError(
                f"{where}: expected INSTANCE.NAME=VALUE with INSTANCE one of {', '.join(INSTANCES)}"
            )
        text = text.strip()
        if inst == "controller" and name == "law":
            out[key.strip()] = parse_law(text, where)
            continue
        value: float | int | bool
        if text in ("true", "false"):
            value = text == "true"
        elif re.fullmatch(r"[-+]?\d{1,40}", text):
            value = int(text)
        else:
            try:
                value = float(text)
            except ValueError:
                value = parse_number(text, where, key.strip())
        out[key.strip()] = value
    return out
