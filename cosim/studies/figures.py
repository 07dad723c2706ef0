"""The report's paper figures (their runs: :data:`FIGURES`) and what is read off a run."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..runner.metrics import describe_outcome, speed_stop
from ..runner.outcome import wrap_angle
from ..runner.run import RunResult
from ..scenarios.fields import LAWS
from ..scenarios.scenario import Scenario

DEG = 180.0 / math.pi
__all__ = [
    "DEG",
    "FIGURES",
    "Figure",
    "Run",
    "estimation_error",
    "fmt",
    "how_it_ends",
    "passivity_gain",
    "stop_reason",
]


@dataclass(frozen=True)
class Run:
    """One run of a figure: a label, a shipped scenario and parameter overrides."""

    label: str
    scenario: str
    overrides: dict[str, Any] = field(default_factory=dict)
    group: str = ""  # the panel column it is drawn in (figures with ``by_group``)


@dataclass(frozen=True)
class Figure:
    """A paper figure: its runs and the columns plotted (one panel each)."""

    key: str
    title: str
    runs: tuple[Run, ...]
    panels: tuple[tuple[str, str], ...]  # (column, y label)
    by_group: bool = False  # one column of panels per Run.group
    share_y: bool = True  # one y-range per row (else per panel)


SEC53 = "sec53-protocol"


FIGURES: tuple[Figure, ...] = (
    Figure(
        "fig2", "Fig. 2: open loop against closed loop (full-state feedback)",
        (Run("open loop", "fig2-open-loop"), Run("K_c = 2 (paper)", "fig2-closed-loop"),
         Run("K_c = 10", "fig2-closed-loop", {"controller.K_c": 10.0})),
        (("plant.theta_g", "glide angle theta_g [deg]"),),
    ),
    Figure(
        "fig3-4", "Figs. 3-4: effect of K_c (full-state feedback)",
        tuple(Run(f"K_c = {k:g}", "fig3-4-kc", {"controller.K_c": float(k)},
                  "K_c = 2, 3, 6" if k < 7 else "K_c = 8, 10, 20")
              for k in (2, 3, 6, 8, 10, 20)),
        (("controller.delta_cmd", "tail command delta_cmd [deg] (Fig. 3)"),
         ("plant.theta_g", "glide angle theta_g [deg] (Fig. 4)")),
        by_group=True, share_y=False,
    ),
    Figure(
        "fig5-6", "Figs. 5-6: observer under noise R = 0.1 rad^2 (full-state feedback; the "
        "observer runs outside the loop)",
        (Run("K_c = 10", "fig5-6-observer-noise"),
         Run("K_c = 2 (paper)", "fig5-6-observer-noise", {"controller.K_c": 2.0})),
        (("plant.theta_meas", "measured pitch [deg] (Fig. 5)"),
         ("observer.theta_g_hat", "estimated glide angle [deg] (Fig. 6)"),
         ("plant.theta_g", "true glide angle [deg] (Fig. 6)")),
    ),
    Figure(
        "fig11-20", "Figs. 11-20: Sec. 5.3 protocol (2 deg hold, observer feedback), the "
        "paper's gains and stable ones",
        (Run("passivity K_c = 1", SEC53, {"controller.K_c": 1.0}, "passivity law"),
         Run("passivity K_c = 3", SEC53, {"controller.K_c": 3.0}, "passivity law"),
         Run("P K_P = 2", SEC53, {"event.controller.law": "p", "controller.K_P": 2.0}, "P law"),
         Run("P K_P = 3", SEC53, {"event.controller.law": "p", "controller.K_P": 3.0}, "P law"),
         Run("PI K_P = 2, K_I = 1 Hz", SEC53,
             {"event.controller.law": "pi", "controller.K_P": 2.0, "controller.K_I": 1.0},
             "PI law"),
         Run("PI K_P = 2, K_I = 3 Hz", SEC53,
             {"event.controller.law": "pi", "controller.K_P": 2.0, "controller.K_I": 3.0},
             "PI law"),
         Run("passivity K_c = 10 (ours)", SEC53, {"controller.K_c": 10.0}, "passivity law"),
         Run("P K_P = 0.5 (ours)", SEC53, {"event.controller.law": "p", "controller.K_P": 0.5},
             "P law"),
         Run("PI K_P = 0.5, K_I = 0.2 Hz (ours)", SEC53,
             {"event.controller.law": "pi", "controller.K_P": 0.5, "controller.K_I": 0.2},
             "PI law")),
        (("plant.theta_g", "glide angle theta_g [deg]"), ("plant.theta", "pitch theta [deg]"),
         ("controller.delta_cmd", "tail command [deg]")),
        by_group=True,
    ),
)  # fmt: skip


def fmt(v: Any, scale: float = 1.0, digits: int = 2) -> str:
    """A number for the report's tables (scaled, fixed digits; ``n/a`` if missing)."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    return f"{v * scale:.{digits}f}"


def estimation_error(r: RunResult) -> tuple[float, float, float, float] | None:
    """RMS and max |theta_g_hat - theta_g| [rad], the difference wrapped to [-pi, pi)
    (:func:`~glider_cosim.runner.outcome.wrap_angle`), over the second half of the
    recorded run (after the observer's initial transient), and that window's start and
    end [s]; None without an observer."""
    if "observer.theta_g_hat" not in r.columns or len(r.data) < 2:
        return None
    t = r.data[:, 0]
    i0 = int(np.searchsorted(t, 0.5 * (t[0] + t[-1])))
    err = wrap_angle(r.column("observer.theta_g_hat") - r.column("plant.theta_g"))[i0:]
    return float(np.sqrt(np.mean(err**2))), float(np.max(np.abs(err))), float(t[i0]), float(t[-1])


def passivity_gain(sc: Scenario) -> float | None:
    """K_c of a scenario whose controller ends on the passivity law (after its events),
    else None."""
    ctrl = sc.parameters.get("controller", {})
    law = ctrl.get("law", LAWS["open-loop"])
    for ev in sc.events:
        law = ev.actions.get("controller.law", law)
    return float(ctrl["K_c"]) if law == LAWS["passivity"] and "K_c" in ctrl else None


def how_it_ends(r: RunResult) -> str:
    """How a run ends, in a few words: a cell of the K_c map, a heading of Figs. 11-20."""
    m = r.metrics
    if m.get("outcome") == "settled":
        return f"settled in {m['settling_time_s']:.2f} s"
    if r.status != "ok":
        reason = stop_reason(r)
        if reason:
            name, verb = reason.split()[:2]
            return f"stops at {r.data[-1, 0]:.2f} s ({name} {verb})"
        return f"stops at {r.data[-1, 0]:.2f} s"
    return describe_outcome(m, brief=True)


def stop_reason(r: RunResult) -> str | None:
    """How a stopped run's speed ended, or None if it did not stop on it:
    ``V_hat stalls at 4.70 s (V_hat = -0.013 m/s)`` for a speed that fell to about zero
    (:func:`glider_cosim.runner.metrics.speed_stop`), else
    ``V_hat diverges at 38.80 s (V_hat = -2.5e+02 m/s)``."""
    found = speed_stop(r.message or "")
    if found is None:
        return None
    name, v, verb = found
    return f"{name} {verb} at {float(r.data[-1, 0]):.2f} s ({name} = {v:.2g} m/s)"
