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

import ctypes
import math
import re
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

from .outcome import MIN_HOLD_S, SETTLED, STOPPED, TUMBLING, classify, wrap_angle
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
    o = classify(tt, e_turns, band, period=2.0 * math.pi)
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
    or a 2-D numpy array. The metrics are computed by the C helper's kernel
    (``glidemetrics.c``, no numpy) where it can, else by :func:`glide_metrics` (numpy),
    to the same bits.
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
    completed = status == "ok"
    glide = _glide_metrics_c(data, which, theta_ge, t_on, completed)
    if glide is None:
        table = data.array() if isinstance(data, Table) else data
        # contiguous copies of the columns: numpy runs faster on them (a row-major
        # table's columns are strided views), to the same values
        import numpy as np

        t, theta_g, delta_cmd = (np.ascontiguousarray(table[:, k]) for k in which)
        glide = glide_metrics(t, theta_g, delta_cmd, theta_ge, t_on, completed=completed)
    metrics.update(glide)
    metrics["V_e_m_s"] = v_e
    return metrics


# the kernel's codes and slots (glidemetrics.c)
_GM_NUMPY, _GM_NONE, _GM_STOPPED, _GM_SETTLED, _GM_TUMBLING, _GM_FIT_PEAKS, _GM_FIT_WINDOW = (
    -1, 0, 1, 2, 3, 4, 5)  # fmt: skip
(_EFFORT, _MAXABS, _RISE, _OVER, _OVER_PCT, _BAND, _FINAL, _SETTLING, _PERIOD, _RATE, _WIN0,
 _WIN1, _HOLD, _IN_BAND, _I0, _AMP, _MINABS, _E0, _NFIT, _TW0, _TW1,
 _SLOTS) = range(22)  # fmt: skip
_KERNEL: list[Any] = []  # [lib or None], found once


def _kernel() -> Any:
    """The C helper with its metrics kernels' signatures set, or None (no compiler,
    ``GLIDER_COSIM_FASTLOOP=0``)."""
    if not _KERNEL:
        from ..master.fastloop import library

        lib = library()
        if lib is not None:
            c_long, c_double, c_int, ptr = (ctypes.c_long, ctypes.c_double, ctypes.c_int,
                                            ctypes.c_void_p)  # fmt: skip
            f = lib.glider_glide_metrics
            f.restype = c_long
            f.argtypes = (ptr, c_long, c_long, c_long, c_long, c_long, c_double, c_int, c_double,
                          c_int, c_double, ptr, ptr, ptr)  # fmt: skip
            g = lib.glider_wrapped_rms
            g.restype = c_int
            g.argtypes = (ptr, c_long, c_long, c_long, c_long, ptr)
        _KERNEL.append(lib)
    return _KERNEL[0]


def _address(data: Table | np.ndarray) -> tuple[int, Any] | None:
    """Where a table's doubles are, row-major (and what keeps them alive), or None."""
    if isinstance(data, Table):
        return data.address(), data
    flags = getattr(data, "flags", None)
    if flags is None or not flags.c_contiguous or data.dtype.str != "<f8" or data.ndim != 2:
        return None
    return data.ctypes.data, data


def _glide_metrics_c(
    data: Table | np.ndarray, which: tuple[int, int, int], theta_ge: float, t_on: float | None,
    completed: bool,
) -> dict[str, Any] | None:  # fmt: skip
    """:func:`glide_metrics` of the table's columns ``which`` (time, ``plant.theta_g``,
    ``controller.delta_cmd``) by the C kernel, to the same bits (where a fit decides the
    outcome, the kernel hands back the points and numpy fits them); None where numpy
    must compute them all (a value is not finite, no C helper)."""
    lib = _kernel()
    where = _address(data) if lib is not None else None
    if where is None:
        return None
    nrows, ncol = len(data), (data.ncol if isinstance(data, Table) else data.shape[1])
    v = (ctypes.c_double * _SLOTS)()
    mask = ctypes.c_long(0)
    fit = (ctypes.c_double * (2 * nrows))()
    code = lib.glider_glide_metrics(
        where[0], nrows, ncol, *which, theta_ge, t_on is not None,
        0.0 if t_on is None else t_on - 1e-9, completed, BAND_FLOOR, v, ctypes.byref(mask), fit,
    )  # fmt: skip
    if code == _GM_NUMPY:
        return None
    none = mask.value

    def val(slot: int) -> float | None:
        return None if none >> slot & 1 else v[slot]

    out: dict[str, Any] = {"theta_ge_rad": theta_ge, "t_on_s": t_on, **_OUTCOME_NONE}
    out["control_effort"] = v[_EFFORT]
    out["max_abs_delta_cmd_rad"] = v[_MAXABS]
    if int(v[_I0]) >= nrows:
        out.update(rise_time_s=None, overshoot_rad=None, overshoot_pct=None, settling_time_s=None)
        out["outcome"] = None if completed else STOPPED
        return out
    out["settling_band_rad"] = v[_BAND]
    out["final_error_rad"] = v[_FINAL]
    out.update(rise_time_s=val(_RISE), overshoot_rad=v[_OVER], overshoot_pct=val(_OVER_PCT))
    out["settling_time_s"] = None
    if code == _GM_STOPPED:
        out["outcome"] = STOPPED
    elif code == _GM_SETTLED:
        out.update(settling_time_s=v[_SETTLING], outcome=SETTLED, outcome_period_s=val(_PERIOD),
                   settling_hold_s=v[_HOLD], in_band_s=v[_IN_BAND])  # fmt: skip
    elif code == _GM_TUMBLING:
        out.update(outcome=TUMBLING, outcome_period_s=val(_PERIOD), outcome_rate_per_s=v[_RATE],
                   outcome_window_s=[v[_WIN0], v[_WIN1]], settling_hold_s=MIN_HOLD_S)  # fmt: skip
    elif code in (_GM_FIT_PEAKS, _GM_FIT_WINDOW):
        status, sigma = _fitted(code, v, fit, nrows)
        out.update(outcome=status, outcome_period_s=val(_PERIOD), outcome_amplitude_rad=v[_AMP],
                   outcome_rate_per_s=sigma, outcome_window_s=[v[_WIN0], v[_WIN1]],
                   settling_hold_s=v[_HOLD], in_band_s=val(_IN_BAND))  # fmt: skip
    return out


def _fitted(code: int, v: Any, fit: Any, nrows: int) -> tuple[str, float]:
    """The outcome of an error that neither settled nor tumbled, and its rate [1/s]:
    numpy's fit of the kernel's points (as :func:`~glider_cosim.runner.outcome.classify`)."""
    import numpy as np

    from .outcome import _fit_rate, envelope_status, trend_status

    m = int(v[_NFIT])
    x = np.frombuffer(fit, dtype=float, count=m).copy()
    sigma = _fit_rate(x, np.frombuffer(fit, dtype=float, count=m, offset=8 * nrows).copy())
    if code == _GM_FIT_PEAKS:  # the envelope of an oscillation
        return envelope_status(sigma, v[_PERIOD]), sigma
    return trend_status(sigma, v[_TW1] - v[_TW0], v[_MINABS], v[_E0]), sigma


def wrapped_rms(data: Table | np.ndarray, a: int, b: int) -> float:
    """``sqrt(mean(wrap_angle(column a - column b) ** 2))`` of a table (rad): by the C
    kernel where it can, else numpy, to the same bits."""
    lib = _kernel()
    where = _address(data) if lib is not None else None
    if where is not None:
        rms = ctypes.c_double(0.0)
        ncol = data.ncol if isinstance(data, Table) else data.shape[1]
        if lib.glider_wrapped_rms(where[0], len(data), ncol, a, b, ctypes.byref(rms)) == 0:
            return rms.value
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
