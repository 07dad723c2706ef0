"""Performance metrics of a glide-stabilisation run (definitions in README, "Metrics").

All are computed on the true glide angle ``plant.theta_g`` against the plant's
open-loop equilibrium ``theta_ge``, from the time the controller takes over ``t_on``
(its ``t_enable``, or the time an event last changed the controller):

- ``rise_time_s``: first time after ``t_on`` the error has shrunk to 10 % of its value
  at ``t_on`` (i.e. 90 % of the way to the equilibrium).
- ``overshoot_rad`` / ``overshoot_pct``: largest excursion past the equilibrium
  (opposite sign to the initial error), in rad and in % of the initial error.
- ``settling_time_s``: time after ``t_on`` from which the error stays within the band
  ``max(2 % of the initial error, 0.1 deg)`` to the end of the run (None if never).
- ``control_effort``: integral of ``|delta_cmd|`` dt over the run, rad s (held values).
- ``max_abs_delta_cmd_rad``: largest ``|delta_cmd|``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

BAND_FRACTION = 0.02
BAND_FLOOR = math.radians(0.1)


def takeover_time(params: dict[str, Any], events: Sequence[Any]) -> float | None:
    """When the controller takes over: its t_enable or the last event acting on it.

    None if an event that acts on the controller never fired (it never took over).
    """
    t_on = float(params.get("t_enable", 0.0))
    for ev in events:
        if any(a.startswith("controller.") for a in ev.actions):
            if ev.fired_at is None:
                return None
            t_on = max(t_on, ev.fired_at + ev.delay)
    return t_on


def glide_metrics(
    t: np.ndarray, theta_g: np.ndarray, delta_cmd: np.ndarray, theta_ge: float, t_on: float | None
) -> dict[str, float | None]:
    """Metrics of one trajectory (see the module docstring); arrays in s and rad."""
    out: dict[str, float | None] = {"theta_ge_rad": theta_ge, "t_on_s": t_on}
    h = float(t[1] - t[0]) if len(t) > 1 else 0.0
    out["control_effort"] = float(np.sum(np.abs(delta_cmd[:-1])) * h) if len(t) > 1 else 0.0
    out["max_abs_delta_cmd_rad"] = float(np.max(np.abs(delta_cmd))) if len(t) else 0.0
    i0 = len(t) if t_on is None else int(np.searchsorted(t, t_on - 1e-9))
    if i0 >= len(t):
        out.update(rise_time_s=None, overshoot_rad=None, overshoot_pct=None, settling_time_s=None)
        return out
    e = theta_g[i0:] - theta_ge
    tt = t[i0:] - t[i0]
    e0 = float(e[0])
    if abs(e0) < 1e-12:
        out.update(rise_time_s=0.0, overshoot_rad=0.0, overshoot_pct=0.0, settling_time_s=0.0)
        return out
    inside = np.abs(e) <= 0.1 * abs(e0)
    out["rise_time_s"] = float(tt[np.argmax(inside)]) if inside.any() else None
    past = -np.sign(e0) * e
    over = max(0.0, float(np.max(past)))
    out["overshoot_rad"] = over
    out["overshoot_pct"] = 100.0 * over / abs(e0) if abs(e0) >= BAND_FLOOR else None
    band = max(BAND_FRACTION * abs(e0), BAND_FLOOR)
    outside = np.nonzero(np.abs(e) > band)[0]
    if len(outside) == 0:
        out["settling_time_s"] = 0.0
    elif outside[-1] == len(e) - 1:
        out["settling_time_s"] = None
    else:
        out["settling_time_s"] = float(tt[outside[-1] + 1])
    out["settling_band_rad"] = band
    out["final_error_rad"] = float(e[-1])
    return out


def compute_metrics(columns: Sequence[str], data: np.ndarray, scenario: Any, sim: Any) -> dict:
    """Metrics of a run's table (needs ``plant.theta_g`` and ``controller.delta_cmd``)."""
    metrics: dict[str, Any] = {
        "scenario": scenario.name,
        "scenario_source": scenario.source,
        "coupling": sim.coupling,
        "step_s": sim.step_size,
        "rows": int(len(data)),
        "end_time_s": float(data[-1, 0]) if len(data) else None,
    }
    if len(data) == 0 or "plant.theta_g" not in columns or "controller.delta_cmd" not in columns:
        return metrics
    p = GliderParams.from_mapping(sim.system.parameters.get("plant", {}))
    t_on = takeover_time(sim.system.parameters.get("controller", {}), sim.system.events)
    metrics.update(
        glide_metrics(
            data[:, 0],
            data[:, list(columns).index("plant.theta_g")],
            data[:, list(columns).index("controller.delta_cmd")],
            equilibrium(p).theta_g,
            t_on,
        )
    )
    return metrics
