"""Control laws: passivity-based (paper Eqs. (23)-(30)), P, PI with anti-windup, open loop.

All laws return the commanded physical tail angle ``delta_cmd`` in rad, saturated at
``delta_max``; the passivity law computes ``u_delta`` and divides by ``K_udelta``.
"""

from __future__ import annotations

import math
from enum import IntEnum

from glider_plant.model import Equilibrium, saturate
from glider_plant.params import GliderParams


class Law(IntEnum):
    """Value of the controller's ``law`` parameter."""

    OPEN_LOOP = 0
    PASSIVITY = 1
    P = 2
    PI = 3


def passivity_output(V: float, theta_g: float, p: GliderParams, eq: Equilibrium) -> float:
    """Passive output ``y_r`` of the approximated reduced model, Eqs. (23)-(25).

    Parameters
    ----------
    V : float
        Speed (estimate), m/s.
    theta_g : float
        Glide angle (estimate), rad.
    """
    v = (V - eq.V) / eq.V
    th = theta_g - eq.theta_g
    k = p.K_Fdelta / eq.K_De
    one_v = 1.0 + v
    g1 = k * one_v * one_v * math.sin(eq.alpha)
    g2 = k * one_v * math.cos(eq.alpha)
    return (one_v * one_v - math.cos(th)) * g1 + one_v * math.sin(th) * g2


def passivity_law(
    V: float, theta_g: float, K_c: float, p: GliderParams, eq: Equilibrium, delta_max: float
) -> float:
    """Tail command of the passivity-based law, rad.

    ``u_delta = -(1/K_c) arctan(y_r)`` (Eqs. (27)-(28), with the minus sign decided in
    the reading notes), ``delta_cmd = sat(u_delta / K_udelta)``.
    """
    u = -math.atan(passivity_output(V, theta_g, p, eq)) / K_c
    return saturate(u / p.K_udelta, delta_max)


class PIController:
    """P or PI law on the glide-angle error ``e = theta_g_hat - theta_ge`` (rad).

    ``delta_cmd = sat(-(K_P e + K_I integral(e dt)), delta_max)``. Anti-windup by
    conditional integration: the integrator holds while the output is saturated and
    the error would drive it further into saturation.
    """

    def __init__(self, K_P: float, K_I: float, delta_max: float) -> None:
        self.K_P = K_P
        self.K_I = K_I
        self.delta_max = delta_max
        self.integral = 0.0  # rad s

    def output(self, error: float) -> float:
        """Saturated command for the current error (no state change)."""
        return saturate(-(self.K_P * error + self.K_I * self.integral), self.delta_max)

    def update(self, error: float, h: float) -> None:
        """Advance the integrator over a step of ``h`` s with the error held."""
        if self.K_I == 0.0:
            return
        raw = -(self.K_P * error + self.K_I * self.integral)
        winding_up = (raw > self.delta_max and -error > 0.0) or (
            raw < -self.delta_max and -error < 0.0
        )
        if not winding_up:
            self.integral += error * h
