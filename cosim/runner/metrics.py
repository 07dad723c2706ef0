"""Performance metrics of a glide-stabilisation run (definitions: docs/reference/results.md,
"Metrics").

All are computed on the true glide angle ``plant.theta_g`` against the glide angle the
loop should reach (:func:`reference_glide_angle`: the equilibrium ``theta_ge``, or for an
open-loop law with a held tail the steady glide with that tail; ``theta_ge_rad`` in the
metrics), from the time the controller takes over ``t_on`` (its ``t_enable``, or the time
an event last changed the controller):

- ``rise_time_s``: first time after ``t_on`` the error has shrunk to 10 % of its value
  at ``t_on`` (i.e. 90 % of the way to the equilibrium).
- ``overshoot_rad`` / ``overshoot_pct``: largest excursion past the equilibrium
  (opposite sign to the initial error), in rad and in % of the initial error.
- ``settling_time_s``: time after ``t_on`` from which the error stays within the band
  ``max(2 % of the initial error, 0.1 deg)`` to the end of the run, with enough run
  left to tell (at least ``settling_hold_s`` = max(10 s, 3 periods of the slowest
  oscillation seen in the error)); None otherwise.
- ``outcome``: ``settled``, ``not settled`` (still converging, or an offset),
  ``limit cycle``, ``diverging``, ``tumbling`` (more than a full turn of the glide angle
  at the end; the error is otherwise taken modulo 360 deg) or ``stopped`` (the run
  ended early), detected from the
  trajectory by :func:`glider_cosim.runner.outcome.classify`, with ``outcome_period_s``,
  ``outcome_amplitude_rad`` (mean peak error), ``outcome_rate_per_s`` (envelope growth
  rate, > 0 grows) and ``outcome_window_s`` (the examined end of the run, s).
- ``control_effort``: integral of ``|delta_cmd|`` dt over the run, rad s (held values).
- ``max_abs_delta_cmd_rad``: largest ``|delta_cmd|``.
- ``V_e_m_s``: the speed of that glide (m/s), which ``speed.png`` marks.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

from .outcome import STOPPED, classify, wrap_angle
from .recorders import Table

if TYPE_CHECKING:
    import numpy as np

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


_OUTCOME_NONE = {
    "outcome": None, "outcome_period_s": None, "outcome_amplitude_rad": None,
    "outcome_rate_per_s": None, "outcome_window_s": None, "settling_hold_s": None,
    "in_band_s": None,
}  # fmt: skip


def glide_metrics(
    t: np.ndarray,
    theta_g: np.ndarray,
    delta_cmd: np.ndarray,
    theta_ge: float,
    t_on: float | None,
    completed: bool = True,
) -> dict[str, Any]:
    """Metrics of one trajectory (see the module docstring); arrays in s and rad.

    ``completed=False`` (the run stopped early): the outcome is ``stopped`` and there is
    no settling time.
    """
    import numpy as np

    out: dict[str, Any] = {"theta_ge_rad": theta_ge, "t_on_s": t_on, **_OUTCOME_NONE}
    h = float(t[1] - t[0]) if len(t) > 1 else 0.0
    out["control_effort"] = float(np.sum(np.abs(delta_cmd[:-1])) * h) if len(t) > 1 else 0.0
    out["max_abs_delta_cmd_rad"] = float(np.max(np.abs(delta_cmd))) if len(t) else 0.0
    i0 = len(t) if t_on is None else int(np.searchsorted(t, t_on - 1e-9))
    if i0 >= len(t):
        out.update(rise_time_s=None, overshoot_rad=None, overshoot_pct=None, settling_time_s=None)
        out["outcome"] = None if completed else STOPPED  # the controller never took over
        return out
    e_turns = theta_g[i0:] - theta_ge  # unwrapped: a tumbling glider adds turns
    e = wrap_angle(e_turns)  # the same glide, modulo 360 deg
    tt = t[i0:] - t[i0]
    e0 = float(e[0])
    band = max(BAND_FRACTION * abs(e0), BAND_FLOOR)
    out["settling_band_rad"] = band
    out["final_error_rad"] = float(e[-1])
    if abs(e0) < 1e-12:
        out.update(rise_time_s=0.0, overshoot_rad=0.0, overshoot_pct=0.0)
    else:
        inside = np.abs(e) <= 0.1 * abs(e0)
        out["rise_time_s"] = float(tt[np.argmax(inside)]) if inside.any() else None
        past = -np.sign(e0) * e
        over = max(0.0, float(np.max(past)))
        out["overshoot_rad"] = over
        out["overshoot_pct"] = 100.0 * over / abs(e0) if abs(e0) >= BAND_FLOOR else None
    out["settling_time_s"] = None
    if not completed:
        out["outcome"] = STOPPED
        return out
    if len(e) < 2:
        return out
    o = classify(tt, e_turns, band, period=2.0 * math.pi, wrapped=e)
    out.update(
        settling_time_s=o.settling_time_s,
        outcome=o.status,
        outcome_period_s=o.period_s,
        outcome_amplitude_rad=o.amplitude,
        outcome_rate_per_s=o.rate_per_s,
        outcome_window_s=None if o.window_s is None else [w + float(t[i0]) for w in o.window_s],
        settling_hold_s=o.hold_required_s,
        in_band_s=o.in_band_s,
    )
    return out


_SPEED_CHECK = re.compile(
    r"(\w+): (?:observer estimate )?glider stalled: V = ([-+]?(?:nan|inf)|[-+0-9.eE]+) m/s"
)
#: the most negative speed [m/s] a stopped run's V may have for it to count as a stall
#: (its speed fell to about zero, crossing the model's limit within one step); beyond it,
#: or not finite, the state or estimate diverged
STALL_FLOOR = -0.1


def speed_stop(message: str) -> tuple[str, float, str] | None:
    """What the models' speed check (V above their limit) says in an FMU's message:
    ``(name, V, verb)``, ``name`` ``V`` (the plant) or ``V_hat`` (the observer's
    estimate), ``V`` in m/s, ``verb`` ``stalls`` (V fell to about zero: above
    :data:`STALL_FLOOR`) or ``diverges`` (beyond it, or not finite); None if the
    message is not the speed check's."""
    m = _SPEED_CHECK.search(message)
    if not m:
        return None
    v = float(m.group(2))
    verb = "stalls" if math.isfinite(v) and v > STALL_FLOOR else "diverges"
    return ("V_hat" if m.group(1) == "observer" else "V"), v, verb


def reference_glide_angle(
    p: GliderParams, controller: dict[str, Any], events: Sequence[Any] = ()
) -> float:
    """The glide angle [rad] the loop should reach: the equilibrium ``theta_ge`` for the
    passivity, P and PI laws (they drive the tail to 0 there); for the open-loop law
    (after the events) the steady glide with its tail ``delta_open`` held
    (:func:`glider_cosim.runner.heldtail.held_glide`)."""
    return reference_glide(p, controller, events)[0]


def reference_glide(
    p: GliderParams, controller: dict[str, Any], events: Sequence[Any] = ()
) -> tuple[float, float]:
    """The glide the loop should reach (:func:`reference_glide_angle`): its glide angle
    [rad] and speed [m/s]."""
    law, delta_open = controller.get("law", 1), controller.get("delta_open", 0.0)
    for ev in events:
        law = ev.actions.get("controller.law", law)
        delta_open = ev.actions.get("controller.delta_open", delta_open)
    if int(law) != 0 or delta_open == 0.0:
        eq = equilibrium(p)
        return eq.theta_g, eq.V
    from .heldtail import held_glide  # numpy's eigenvalues: only for this law

    held = held_glide(p, p.K_udelta * float(delta_open))
    return held.theta_g, held.V


def compute_metrics(
    columns: Sequence[str], data: Table | np.ndarray, scenario: Any, sim: Any, status: str = "ok"
) -> dict:
    """Metrics of a run's table (needs ``plant.theta_g`` and ``controller.delta_cmd``);
    ``status`` other than ``"ok"`` (the run ended early) makes the outcome ``stopped``.

    ``data``: the rows, time first (s), as a :class:`~glider_cosim.runner.recorders.Table`
    or a 2-D numpy array. The metrics are :func:`glide_metrics`'s (numpy).
    """
    n = len(data)
    end = (data.value(-1, 0) if isinstance(data, Table) else float(data[-1, 0])) if n else None
    metrics: dict[str, Any] = {
        "scenario": scenario.name,
        "scenario_source": scenario.source,
        "coupling": sim.coupling,
        "step_s": sim.step_size,
        "rows": int(n),
        "end_time_s": end,
    }
    if n == 0 or "plant.theta_g" not in columns or "controller.delta_cmd" not in columns:
        return metrics
    p = GliderParams.from_mapping(sim.system.parameters.get("plant", {}))
    ctrl = sim.system.parameters.get("controller", {})
    t_on = takeover_time(ctrl, sim.system.events)
    theta_ge, v_e = reference_glide(p, ctrl, sim.system.events)
    cols = list(columns)
    which = (0, cols.index("plant.theta_g"), cols.index("controller.delta_cmd"))
    table = data.array() if isinstance(data, Table) else data
    # contiguous copies of the columns: numpy runs faster on them (a row-major table's
    # columns are strided views), to the same values
    import numpy as np

    t, theta_g, delta_cmd = (np.ascontiguousarray(table[:, k]) for k in which)
    glide = glide_metrics(t, theta_g, delta_cmd, theta_ge, t_on, completed=status == "ok")
    metrics.update(glide)
    metrics["V_e_m_s"] = v_e
    return metrics


def wrapped_rms(data: Table | np.ndarray, a: int, b: int) -> float:
    """``sqrt(mean(wrap_angle(column a - column b) ** 2))`` of a table's columns ``a`` and
    ``b`` (angles in rad), in rad."""
    import numpy as np

    table = data.array() if isinstance(data, Table) else np.asarray(data, dtype=float)
    err = wrap_angle(table[:, a] - table[:, b])
    return float(np.sqrt(np.mean(err**2)))


def describe_outcome(m: dict[str, Any], brief: bool = False) -> str:
    """The outcome of a run's metrics in words, with units (angles in deg).

    E.g. ``"settled in 10.48 s"``, ``"limit cycle: amplitude 1.94 deg, period 1.75 s"``,
    ``"diverging: envelope grows at 0.225 1/s"``; ``brief``: a table cell
    (``"limit cycle 1.94 deg, 1.75 s"``).
    """
    o = m.get("outcome")
    if o is None:
        return "n/a" if brief else "no outcome (the controller never took over)"
    if o == "settled":
        return o if brief else f"settled in {m['settling_time_s']:.2f} s"
    if o == STOPPED:
        end = m.get("end_time_s")
        at = "" if end is None else f" at {end:.2f} s"
        return f"stopped{at}" if brief else f"stopped{at} (the run ended early)"
    keys = ("outcome_amplitude_rad", "outcome_period_s", "outcome_rate_per_s")
    amp, per, rate = (m.get(k) for k in keys)
    if o == "limit cycle":
        if brief:
            return f"limit cycle {math.degrees(amp):.2f} deg, {per:.2f} s"
        return f"limit cycle: amplitude {math.degrees(amp):.2f} deg, period {per:.2f} s"
    if o == "tumbling":
        w0, w1 = m["outcome_window_s"]
        turns = abs(rate) * (w1 - w0)
        if brief:
            return f"tumbling {abs(rate):.3g} turns/s"
        return f"tumbling: {turns:.1f} turns over {w0:.1f}-{w1:.1f} s ({per:.1f} s per turn)"
    if o == "diverging":
        return (
            f"diverging {rate:+.3g} 1/s"
            if brief
            else f"diverging: envelope grows at {rate:.3g} 1/s"
        )
    if brief:
        return f"not settled ({rate:+.3g} 1/s)"
    w0, w1 = m["outcome_window_s"]
    text = f"not settled: |error| about {math.degrees(amp):.2f} deg over {w0:.1f}-{w1:.1f} s"
    if rate < 0:
        text += f", still decaying at {-rate:.3g} 1/s"
    if m.get("in_band_s") is not None:
        text += (
            f"; in the band for the last {m['in_band_s']:.1f} s of the "
            f"{m['settling_hold_s']:.1f} s required"
        )
    return text
