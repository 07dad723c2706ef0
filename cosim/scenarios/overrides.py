"""Overrides of a scenario's parameters and events (the report's and sweeps' variants)."""

from __future__ import annotations

import copy
from typing import Any

from glider_cosim.scenarios.scenario import LAWS, Scenario


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
