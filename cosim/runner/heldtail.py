"""The glider with its tail held at a fixed angle (paper Sec. 5.2 and the Sec. 5.3 hold).

A held tail ``delta`` acts on the model only through ``u = K_udelta * delta``
(Eqs. (6)-(9)), so everything here is computed in ``u`` and converted: the steady glide
for a held ``u`` in closed form, its stability (eigenvalues of Eqs. (6)-(9) there), the
largest ``u`` whose steady glide is stable (bisection), and a check by simulation from
the release state. The largest held tail the model carries is then
``delta_max = u_max / K_udelta``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glider_plant.model import StallError, derivatives, equilibrium, plant_step
from glider_plant.params import GliderParams

from .outcome import Outcome, classify


class HeldTailError(ValueError):
    """A held-tail query is out of range (the message says what was expected)."""


@dataclass(frozen=True)
class HeldGlide:
    """Steady glide with ``u_delta`` held: speed [m/s], glide angle, angle of attack [rad],
    and the linearisation's eigenvalue with the largest real part [1/s] (``max_real`` < 0:
    stable)."""

    u: float
    V: float
    theta_g: float
    alpha: float
    critical: complex

    @property
    def max_real(self) -> float:
        return self.critical.real

    @property
    def stable(self) -> bool:
        return self.max_real < 0.0


def held_glide(p: GliderParams, u: float) -> HeldGlide:
    """The steady glide of Eqs. (6)-(9) with ``u_delta = u`` [rad] held, and its stability.

    With ``omega2 = 0`` Eq. (9) gives ``alpha = u - K_M0 / K_M``; Eqs. (6)-(7) then give the
    glide angle and speed from the drag-like and lift-like coefficients (lift, drag and
    the tail force ``K_Fdelta V^2 u``).

    Raises
    ------
    HeldTailError
        If ``u`` is not finite.
    """
    if not math.isfinite(u):
        raise HeldTailError(f"u = {u!r} is invalid: expected a finite angle in rad")
    al = u - p.K_M0 / p.K_M
    d = p.K_D0 + p.K_D * al * al - p.K_Fdelta * u * math.sin(al)
    lift = p.K_L0 + p.K_L * al + p.K_Fdelta * u * math.cos(al)
    th = math.atan2(-d, lift)
    V = math.sqrt(abs(p.m0) * p.g / math.hypot(d, lift))
    x0 = np.array([V, th, al, 0.0])
    J = np.empty((4, 4))
    for i in range(4):
        dx = np.zeros(4)
        dx[i] = 1e-7 * max(1.0, abs(x0[i]))
        fp = np.array(derivatives(0.0, tuple(x0 + dx), u, p))
        fm = np.array(derivatives(0.0, tuple(x0 - dx), u, p))
        J[:, i] = (fp - fm) / (2 * dx[i])
    ev = np.linalg.eigvals(J)
    return HeldGlide(u, V, th, al, complex(ev[np.argmax(ev.real)]))


def largest_carried_u(p: GliderParams, u_high: float = math.radians(60.0)) -> float:
    """Largest held ``u_delta`` [rad] in ``[0, u_high]`` up to which the steady glide is
    stable (the first loss of stability, by a grid of 0.1 deg and bisection to 1e-6 deg).

    Raises
    ------
    HeldTailError
        If the steady glide at ``u = 0`` is not stable (nothing is carried).
    """
    if not held_glide(p, 0.0).stable:
        raise HeldTailError("the open-loop glide (u = 0) is not stable: no held tail is carried")
    grid = np.arange(0.0, u_high + 1e-12, math.radians(0.1))
    lo = 0.0
    for u in grid[1:]:
        if not held_glide(p, float(u)).stable:
            hi = float(u)
            break
        lo = float(u)
    else:
        return float(u_high)
    while hi - lo > math.radians(1e-6):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if held_glide(p, mid).stable else (lo, mid)
    return lo


def release_run(
    p: GliderParams, delta: float, stop_time: float = 120.0, h: float = 0.02
) -> tuple[str, float, Outcome | None]:
    """Simulate the plant alone from the steady glide with the tail at 0, the tail held at
    ``delta`` [rad] from t = 0 (servo 10 ms), for ``stop_time`` s.

    Returns
    -------
    (status, end time [s], outcome)
        ``status`` is ``"stall"`` (V fell to the stall limit; outcome None) or ``"ok"``,
        with the :func:`~glider_cosim.runner.outcome.classify` outcome of the glide angle
        against the held-tail steady glide (band 0.1 deg).
    """
    e = equilibrium(p)
    target = held_glide(p, p.K_udelta * delta).theta_g
    x = (e.V, e.theta_g, e.alpha, 0.0, 0.0, 0.0)
    d = 0.0
    n = round(stop_time / h)
    th = np.empty(n + 1)
    th[0] = x[1]
    for k in range(n):
        try:
            x, d = plant_step(x, d, delta, h, p, 0.01)
        except StallError:
            return "stall", (k + 1) * h, None
        th[k + 1] = x[1]
    t = np.arange(n + 1) * h
    return "ok", float(t[-1]), classify(t, th - target, math.radians(0.1), 2.0 * math.pi)


def carried(run: tuple[str, float, Outcome | None]) -> bool:
    """A release run that ends in (or still converges to) the held-tail steady glide."""
    status, _, o = run
    if status != "ok" or o is None:
        return False
    return o.status == "settled" or (
        o.status == "not settled" and o.rate_per_s is not None and o.rate_per_s < 0.0
    )


def largest_carried_from_release(
    p: GliderParams, stop_time: float = 120.0, tol_deg: float = 0.01
) -> float:
    """Largest held tail ``delta`` [rad] whose :func:`release_run` is :func:`carried`
    (bisection between 0 and the stability limit ``largest_carried_u / K_udelta``, to
    ``tol_deg``). At most the stability limit: beyond it no steady glide is stable."""
    hi = largest_carried_u(p) / p.K_udelta
    if carried(release_run(p, hi, stop_time)):
        return hi
    lo = 0.0
    while math.degrees(hi - lo) > tol_deg:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if carried(release_run(p, mid, stop_time)) else (lo, mid)
    return lo
