"""Overrides of a scenario: ``--set INSTANCE.NAME=VALUE`` and the report's and sweeps' variants."""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping
from typing import Any

from ..inputs.text import did_you_mean, quote
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
    """``["controller.K_c=6", "plant.theta_g_0=-30 deg"]`` -> overrides (angles in rad).

    A name given twice is refused, naming both items.
    """
    out: dict[str, float | int | bool] = {}
    given: dict[str, str] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        where = f"{source} {quote(item)}"
        _check_key(key, where, bool(sep))
        if key in given:
            raise ScenarioError(
                f"{source} {quote(given[key])} and {where}: {key} is set twice: expected one "
                "value per name"
            )
        given[key] = item
        out[key] = parse_override(key, text, where)
    return out


def parse_overrides(overrides: Mapping[str, Any], source: str = "overrides") -> dict[str, Any]:
    """The API's ``{"controller.K_c": 6, "plant.theta_g_0": "-30 deg"}``: each value a
    number, a boolean, or a string read as ``--set`` reads it (``"0.2 m/s"``, ``"pi"``).

    Raises
    ------
    ScenarioError
        ``overrides['KEY']: ...`` for a key that is not ``INSTANCE.NAME`` or a value that
        is not a number.
    """
    if not isinstance(overrides, Mapping):
        raise TypeError(
            f"{source} {quote(overrides)} is invalid: expected a mapping {{'INSTANCE.NAME': value}}"
        )
    out = {}
    for key, value in overrides.items():
        where = f"{source}[{quote(key)}]"
        if not isinstance(key, str):
            raise ScenarioError(f"{where}: expected a string 'INSTANCE.NAME'")
        out[key.strip()] = parse_override(key.strip(), value, where)
    return out


def _check_key(key: str, where: str, sep: bool = True) -> None:
    inst, dot, name = key.partition(".")
    if not sep or not dot or inst not in INSTANCES or not name:
        raise ScenarioError(
            f"{where}: expected INSTANCE.NAME=VALUE with INSTANCE one of {', '.join(INSTANCES)}"
            + (did_you_mean(inst, INSTANCES) if dot and inst not in INSTANCES else "")
        )


def parse_override(key: str, value: Any, where: str) -> Any:
    """One override's value for ``key`` (``instance.name``): a number or boolean as it is,
    a string as ``--set`` reads it (``"true"``, an integer, a float, ``"X UNIT"``, a law
    name for ``controller.law``); the unit is checked against the variable later."""
    _check_key(key, where)
    if key == "controller.law":
        return parse_law(value.strip() if isinstance(value, str) else value, where)
    if not isinstance(value, str):
        return parse_number(value, where, key)
    text = value.strip()
    if text in ("true", "false"):
        return text == "true"
    if re.fullmatch(r"[-+]?\d{1,40}", text):
        return int(text)
    try:
        return float(text)
    except ValueError:
        return parse_number(text, where, key)


def override_scenario(
    sc: Scenario, overrides: Mapping[str, Any], source: str = "overrides"
) -> Scenario:
    """``sc`` with the API's ``overrides`` (:func:`parse_overrides`) applied and checked as
    ``--set`` is: unit and valid range against our FMUs' variable tables, before anything
    is built; messages name ``overrides['KEY']``.

    Raises
    ------
    ScenarioError, ValueCheckError
        A key, value, unit or range refused (both are ``ValueError``).
    """
    from ..inputs.check import check_ranges

    parsed = parse_overrides(overrides, source)
    sc = apply_overrides(sc, parsed)
    for key in parsed:
        sc.origins[key] = f"{source}[{quote(key)}]"
    params: dict[str, dict[str, Any]] = {}
    for key, value in parsed.items():
        inst, _, name = key.partition(".")
        params.setdefault(inst, {})[name] = value
    check_ranges(params, lambda ref: sc.origins.get(ref, f"{source}[{quote(ref)}]"),
                 set(sc.fmus))  # fmt: skip
    return sc
