"""What a run's error trajectory does at the end: settled, not settled, limit cycle,
diverging or (for an angle) tumbling, detected from the trajectory alone (no model, no
linearisation).

The rules (docs/reference/results.md, "Metrics"):

- For an angle error (``period`` given, 2 pi for the glide angle): **tumbling** if the
  angle turns by more than a full turn within the examined window (below); otherwise the
  error is wrapped to half a turn either side first (:func:`wrap_angle`), and the rules
  below apply.
- **Settled** if the error enters the band and stays inside it to the end, with enough
  run left to tell: the time in the band must be at least ``max(MIN_HOLD_S,
  HOLD_PERIODS * P)``, where ``P`` is the longest oscillation period seen in the error
  (from its zero crossings with a hysteresis of the band; 0 if it does not oscillate).
  A signal that merely passes through the band at a zero crossing of an oscillation
  is in the band for a fraction of a period, so it never qualifies.
- Otherwise the last part of the run (its last third after the takeover, at least
  ``MIN_WINDOW_S`` long) is examined:

  - if the error oscillates (at least two full cycles in that window), the peaks of
    ``|e|`` between zero crossings give the envelope; a least-squares fit of
    ``log(peak)`` against time gives the growth rate ``sigma`` [1/s]. If the amplitude
    changes by less than ``SUSTAINED_PER_PERIOD`` (relative) per period the
    oscillation is a **limit cycle** (amplitude = mean peak, period); if it grows it is
    **diverging** (rate ``sigma``); if it shrinks, **not settled** (still converging).
  - if it does not oscillate, ``log|e|`` is fitted against time; an error that grows
    by more than ``SUSTAINED_PER_PERIOD`` over the window, or stays farther from zero
    over the whole window than it was at the start, is **diverging**; one that shrinks
    is **not settled** (converging), one that stays is **not settled** (an offset).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

MIN_HOLD_S = 10.0
HOLD_PERIODS = 3.0
MIN_WINDOW_S = 10.0
SUSTAINED_PER_PERIOD = 0.01

SETTLED = "settled"
NOT_SETTLED = "not settled"
LIMIT_CYCLE = "limit cycle"
DIVERGING = "diverging"
TUMBLING = "tumbling"
STOPPED = "stopped"
OUTCOMES = (SETTLED, NOT_SETTLED, LIMIT_CYCLE, DIVERGING, TUMBLING, STOPPED)


class TrajectoryError(ValueError):
    """The time and error arrays cannot be classified (lengths, order, values)."""


@dataclass(frozen=True)
class Outcome:
    """The verdict on one error trajectory.

    Attributes
    ----------
    status : str
        One of :data:`OUTCOMES` (``stopped`` is set by the caller for a run that ended
        early; :func:`classify` never returns it).
    settling_time_s : float or None
        Time (from the first sample) after which the error stays in the band, s; only
        when ``status == "settled"``.
    hold_required_s : float
        How long the error had to stay in the band to count as settled, s.
    period_s : float or None
        Oscillation period, s (limit cycle, or an oscillating run that is not settled
        or diverging).
    amplitude : float or None
        Mean peak ``|e|`` in the examined window if ``e`` oscillates there, else the mean
        ``|e|``, in the unit of ``e`` (None when tumbling).
    rate_per_s : float or None
        Envelope growth rate ``sigma`` [1/s] (> 0 grows, < 0 decays); tumbling: turns
        per second (signed), and ``period_s`` the time per turn.
    window_s : tuple of float or None
        Start and end of the examined window, s (same time axis as the input).
    in_band_s : float or None
        How long the error has been in the band at the end of the run, s (None if it
        is outside at the last sample).
    """

    status: str
    settling_time_s: float | None = None
    hold_required_s: float = MIN_HOLD_S
    period_s: float | None = None
    amplitude: float | None = None
    rate_per_s: float | None = None
    window_s: tuple[float, float] | None = None
    in_band_s: float | None = None


def wrap_angle(angle: Any, period: float = 2.0 * math.pi) -> Any:
    """``angle`` wrapped to ``[-period/2, period/2)``: the one wrap of the package (an
    array stays an array).

    Parameters
    ----------
    angle : float or array
        In rad (or in degrees with ``period=360``).
    period : float
        A full turn in the unit of ``angle``: 2 pi [rad] (to ``[-pi, pi)``) or 360 [deg]
        (to ``[-180, 180)``).

    The boundary: exactly ``+period/2`` maps to ``-period/2``, as ``-period/2`` stays.
    A glide one turn from another is the same glide, and an estimate one turn from the
    truth is no error.
    """
    import numpy as np

    half = 0.5 * period
    # np.mod(x, period), bit for bit (numpy's npy_divmod for period > 0: fmod, then
    # period added to a negative remainder, -0.0 made +0.0), in half its time
    m = np.fmod(np.asarray(angle, dtype=float) + half, period)
    m += np.where(m < 0.0, period, 0.0)
    return (m + 0.0) - half


def _crossings(t: np.ndarray, e: np.ndarray, hyst: float, jump: float = math.inf) -> np.ndarray:
    """Times at which ``e`` changes sign, counted only between excursions beyond
    ``+-hyst`` (linear interpolation of the last sign change); a sign change by a step
    larger than ``jump`` (a wrapped angle passing +-180 deg) is not a crossing.

    Vectorised (no loop over the samples); the rule, sample by sample: a sign change
    from a non-zero value is the last change (a jump instead forgets the side the
    signal was on and the sample is skipped); a sample beyond ``+-hyst`` on the other
    side than the last one beyond it is a crossing, at the last change."""
    import numpy as np

    t = np.asarray(t, dtype=float)
    e = np.asarray(e, dtype=float)
    n = len(e)
    if n == 0:
        return np.array([])
    idx = np.arange(n)
    sign = np.sign(e)
    change = np.zeros(n, dtype=bool)
    change[1:] = (sign[1:] != sign[:-1]) & (e[:-1] != 0.0)
    jumped = np.zeros(n, dtype=bool)
    jumped[1:] = change[1:] & (np.abs(e[1:] - e[:-1]) > jump)
    change &= ~jumped
    # the last sign change at or before each sample (-1: none yet)
    last = np.maximum.accumulate(np.where(change, idx, -1))
    side = np.where(e > hyst, 1, np.where(e < -hyst, -1, 0))
    side[jumped] = 0  # a jump's sample is skipped
    # the side before each sample: that of the last sample beyond +-hyst, 0 after a jump
    sets = (side != 0) | jumped
    at = np.maximum.accumulate(np.where(sets, idx, -1))
    before = np.zeros(n, dtype=side.dtype)
    prev = at[:-1]
    before[1:] = np.where(prev >= 0, side[np.maximum(prev, 0)], 0)
    hit = (side != 0) & (before != 0) & (side != before) & (last >= 0)
    j = last[hit]
    a, b = e[j - 1], e[j]
    t0, t1 = t[j - 1], t[j]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(a != b, t0 + (t1 - t0) * a / (a - b), t1)


def oscillation_period(
    t: np.ndarray, e: np.ndarray, hyst: float, jump: float = math.inf
) -> float | None:
    """Longest full period of ``e`` [s] seen between its zero crossings (hysteresis
    ``hyst``; sign changes by steps above ``jump`` ignored): twice the longest interval
    between consecutive crossings, ignoring the first one (the transient). None if ``e``
    crosses fewer than three times."""
    import numpy as np

    c = _crossings(t, e, hyst, jump)
    if len(c) < 3:
        return None
    return float(2.0 * np.max(np.diff(c)[1:] if len(c) > 3 else np.diff(c)))


def _fit_rate(times: np.ndarray, values: np.ndarray) -> float:
    import numpy as np

    v = np.maximum(np.abs(values), 1e-300)
    if len(times) < 2 or np.ptp(times) == 0.0:
        return 0.0
    return float(np.polyfit(times, np.log(v), 1)[0])


def classify(
    t: np.ndarray, e: np.ndarray, band: float, period: float | None = None,
    wrapped: np.ndarray | None = None,
) -> Outcome:  # fmt: skip
    """Classify the error trajectory ``e(t)`` against the band ``|e| <= band``.

    Parameters
    ----------
    t : array of float
        Times, s, strictly increasing (the takeover at ``t[0]``).
    e : array of float
        Error at those times (any unit; ``band`` and the amplitude share it).
    band : float
        Half-width of the settling band, > 0.
    period : float, optional
        ``e`` is an angle defined modulo ``period`` (2 pi for a glide angle), given
        unwrapped: a trajectory that turns by more than ``period`` within the examined
        window is **tumbling**; otherwise the error is wrapped into ``(-period/2,
        period/2]`` first (a glider that loops once and then settles has settled).

    Returns
    -------
    Outcome
        See the module docstring for the rules.

    Raises
    ------
    TrajectoryError
        If the arrays differ in length, have fewer than 2 samples, ``t`` is not strictly
        increasing, a value is not finite, or ``band`` or ``period`` is not > 0.
    """
    import numpy as np

    t = np.asarray(t, dtype=float)
    e = np.asarray(e, dtype=float)
    if t.shape != e.shape or t.ndim != 1 or len(t) < 2:
        raise TrajectoryError(
            f"t and e must be 1-D arrays of the same length >= 2 (got {t.shape} and {e.shape})"
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(e))):
        raise TrajectoryError("t and e must be finite (found NaN or inf)")
    if not np.all(np.diff(t) > 0):
        raise TrajectoryError("t must be strictly increasing")
    if not (math.isfinite(band) and band > 0):
        raise TrajectoryError(f"band = {band!r} is invalid: expected a finite value > 0")
    if period is not None and not (math.isfinite(period) and period > 0):
        raise TrajectoryError(f"period = {period!r} is invalid: expected a finite value > 0")
    width = max(MIN_WINDOW_S, (t[-1] - t[0]) / 3.0)
    i0 = int(np.searchsorted(t, t[-1] - width))
    jump = math.inf
    if period is not None:
        if np.ptp(e[i0:]) > period:
            rate = float((e[-1] - e[i0]) / (t[-1] - t[i0]) / period)  # turns per second
            return Outcome(TUMBLING, None, MIN_HOLD_S, 1.0 / abs(rate) if rate else None,
                           None, rate, (float(t[i0]), float(t[-1])))  # fmt: skip
        e = wrap_angle(e, period) if wrapped is None else np.asarray(wrapped, dtype=float)
        jump = 0.5 * period
    p_osc = oscillation_period(t, e, band, jump)
    hold = max(MIN_HOLD_S, HOLD_PERIODS * (p_osc or 0.0))
    outside = np.nonzero(np.abs(e) > band)[0]
    t_in = t[0] if len(outside) == 0 else (t[outside[-1] + 1] if outside[-1] < len(e) - 1 else None)
    in_band = None if t_in is None else float(t[-1] - t_in)
    if in_band is not None and in_band >= hold:
        return Outcome(SETTLED, float(t_in - t[0]), hold, p_osc, in_band_s=in_band)
    # the end of the run: its last third, at least MIN_WINDOW_S (or all of it)
    tw, ew = t[i0:], e[i0:]
    window = (float(tw[0]), float(tw[-1]))
    peak = float(np.max(np.abs(ew)))
    c = _crossings(tw, ew, 0.1 * peak, jump) if peak > 0 else np.array([])
    if len(c) >= 4:
        # half-cycle peaks of |e| between consecutive crossings
        idx = np.searchsorted(tw, c)
        pk_t, pk_v = [], []
        for a, b in zip(idx[:-1], idx[1:], strict=True):
            k = a + int(np.argmax(np.abs(ew[a:b])))
            pk_t.append(tw[k])
            pk_v.append(abs(ew[k]))
        p = float(2.0 * np.mean(np.diff(c)))
        sigma = _fit_rate(np.array(pk_t), np.array(pk_v))
        amp = float(np.mean(pk_v))
        return Outcome(envelope_status(sigma, p), None, hold, p, amp, sigma, window, in_band)
    sigma = _fit_rate(tw, ew)
    status = trend_status(sigma, tw[-1] - tw[0], float(np.min(np.abs(ew))), float(e[0]))
    return Outcome(status, None, hold, p_osc, float(np.mean(np.abs(ew))), sigma, window, in_band)


def envelope_status(sigma: float, period: float) -> str:
    """The outcome of an oscillation whose envelope grows at ``sigma`` [1/s] (< 0 decays),
    its period ``period`` [s]: a limit cycle if its amplitude changes by less than
    ``SUSTAINED_PER_PERIOD`` a period, else diverging or not settled (still decaying)."""
    if math.expm1(abs(sigma) * period) < SUSTAINED_PER_PERIOD:
        return LIMIT_CYCLE
    return DIVERGING if sigma > 0 else NOT_SETTLED


def trend_status(sigma: float, span: float, least: float, first: float) -> str:
    """The outcome of an error that does not oscillate: ``|e|`` grows at ``sigma`` [1/s]
    over the window's ``span`` [s], its least ``|e|`` there ``least``, ``first`` the error
    at the takeover. Diverging if it grows by more than ``SUSTAINED_PER_PERIOD`` or stays
    farther from zero over the whole window than at the start (e.g. a tumbling glider
    whose angle error keeps growing turn after turn, whatever its local trend); else not
    settled (converging, or an offset)."""
    change = math.expm1(sigma * span)
    away = least > (1.0 + SUSTAINED_PER_PERIOD) * abs(first)
    return DIVERGING if change > SUSTAINED_PER_PERIOD or away else NOT_SETTLED
