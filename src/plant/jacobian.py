"""Exact Jacobian of the plant's continuous-time equations (for linearisation).

Written once from the equations of :mod:`glider_plant.model` (analytic partial
derivatives, no finite differences): the body's Eqs. (6)-(9) (:func:`rhs_jacobian`), and
the whole plant's states and inputs with the kinematics and the servo
(:func:`plant_jacobian`, :func:`plant_derivatives`). The C twins in ``plant_model.c``
give the same bits; the plant FMU's directional derivatives are these.
"""

from __future__ import annotations

import math

from .model import Constants, State6, constants, rhs, saturate
from .params import GliderParams

#: the plant's continuous states, in the order of :func:`plant_jacobian`'s first columns
PLANT_STATES = ("V", "theta_g", "alpha", "omega2", "x", "z", "delta")
#: the plant's inputs, in the order of :func:`plant_jacobian`'s last columns
PLANT_INPUTS = ("delta_cmd", "F_x", "F_z", "M_y")


def rhs_jacobian(
    V: float, th: float, al: float, w: float, u_delta: float, c: Constants,
    F_x: float = 0.0, F_z: float = 0.0, M_y: float = 0.0,
) -> tuple[tuple[float, ...], ...]:  # fmt: skip
    """Exact partial derivatives of :func:`glider_plant.model.rhs` (analytic).

    Returns
    -------
    tuple of 4 rows of 8 floats
        Rows ``(dV/dt, dtheta_g/dt, dalpha/dt, domega2/dt)``; columns ``(V, theta_g,
        alpha, omega2, u_delta, F_x, F_z, M_y)``, in the units of row over column
        (e.g. 1/s for ``d(dV/dt)/dV``).
    """
    m, J2, K_L0, K_L, K_D0, K_D, K_q, K_M0, K_M, K_Fdelta, m0g = c
    V2 = V * V
    s_th = math.sin(th)
    c_th = math.cos(th)
    s_al = math.sin(al)
    c_al = math.cos(al)
    k_lift = K_L0 + K_L * al
    f_delta = K_Fdelta * V2 * u_delta
    f_v = F_x * c_th - F_z * s_th
    f_n = -F_x * s_th - F_z * c_th
    mV = m * V
    dth = (-m0g * c_th + k_lift * V2 + f_delta * c_al + f_n) / mV
    # d(dV/dt): drag (K_D0 + K_D al^2) V^2, thrust of the tail f_delta sin(al)
    V_V = (-2.0 * V * (K_D0 + K_D * al * al) + 2.0 * K_Fdelta * V * u_delta * s_al) / m
    V_th = (-m0g * c_th + f_n) / m
    V_al = (-2.0 * K_D * al * V2 + f_delta * c_al) / m
    V_u = K_Fdelta * V2 * s_al / m
    # d(dtheta_g/dt) = d(N / (m V)) with N the normal force
    th_V = (2.0 * V * k_lift + 2.0 * K_Fdelta * V * u_delta * c_al) / mV - dth / V
    th_th = (m0g * s_th - f_v) / mV
    th_al = (K_L * V2 - f_delta * s_al) / mV
    th_u = K_Fdelta * V2 * c_al / mV
    # d(domega2/dt)
    w_V = 2.0 * V * (K_M0 + K_M * al + K_q * w - K_M * u_delta) / J2
    w_al = K_M * V2 / J2
    w_w = K_q * V2 / J2
    w_u = -K_M * V2 / J2
    return (
        (V_V, V_th, V_al, 0.0, V_u, c_th / m, -s_th / m, 0.0),
        (th_V, th_th, th_al, 0.0, th_u, -s_th / mV, -c_th / mV, 0.0),
        (-th_V, -th_th, -th_al, 1.0, -th_u, s_th / mV, c_th / mV, 0.0),
        (w_V, 0.0, w_al, w_w, w_u, 0.0, 0.0, 1.0 / J2),
    )


def plant_jacobian(
    x: State6,
    delta: float,
    delta_cmd: float,
    disturbance: tuple[float, float, float],
    p: GliderParams,
    tau_servo: float,
    delta_max: float,
) -> list[list[float]]:
    """Exact Jacobian of the plant's continuous-time equations and of its pitch.

    The equations are those :func:`glider_plant.model.plant_step` integrates: Eqs. (6)-(9) with
    ``u_delta = K_udelta delta``, the kinematics ``dx/dt = V cos(theta_g)``,
    ``dz/dt = -V sin(theta_g)`` and the servo ``tau_servo d(delta)/dt =
    saturate(delta_cmd, delta_max) - delta`` (``d saturate / d delta_cmd`` is 1 for
    ``|delta_cmd| <= delta_max``, else 0).

    Parameters
    ----------
    x : tuple of 6 floats
        ``(V, theta_g, alpha, omega2, x, z)`` (m/s, rad, rad, rad/s, m, m).
    delta : float
        Tail angle, rad.
    delta_cmd : float
        Commanded tail angle, rad (before saturation).
    disturbance : tuple of 3 floats
        ``(F_x, F_z, M_y)`` (N, N, N m).
    p : GliderParams
        Model constants.
    tau_servo, delta_max : float
        Servo time constant (s) and tail limit (rad).

    Returns
    -------
    list of 8 rows of 11 floats
        Rows: the time derivatives of :data:`PLANT_STATES`, then the pitch
        ``theta = theta_g + alpha``; columns: :data:`PLANT_STATES`, then
        :data:`PLANT_INPUTS`. SI units of row over column.
    """
    V, th, al, w = x[0], x[1], x[2], x[3]
    ku = p.K_udelta
    F_x, F_z, M_y = disturbance
    body = rhs_jacobian(V, th, al, w, ku * delta, constants(p), F_x, F_z, M_y)
    rows = []
    for r in body:  # states (V, th, al, w), then x, z, delta (u_delta = K_udelta delta)
        rows.append([r[0], r[1], r[2], r[3], 0.0, 0.0, r[4] * ku, 0.0, r[5], r[6], r[7]])
    s_th = math.sin(th)
    c_th = math.cos(th)
    rows.append([c_th, -V * s_th, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    rows.append([-s_th, -V * c_th, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    gain = 1.0 / tau_servo if -delta_max <= delta_cmd <= delta_max else 0.0
    rows.append([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0 / tau_servo, gain, 0.0, 0.0, 0.0])
    rows.append([0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    return rows


def plant_derivatives(
    x: State6,
    delta: float,
    delta_cmd: float,
    disturbance: tuple[float, float, float],
    p: GliderParams,
    tau_servo: float,
    delta_max: float,
) -> tuple[float, ...]:
    """The time derivatives of :data:`PLANT_STATES` (arguments as :func:`plant_jacobian`)."""
    V, th = x[0], x[1]
    F_x, F_z, M_y = disturbance
    d = rhs(V, th, x[2], x[3], p.K_udelta * delta, constants(p), F_x, F_z, M_y)
    servo = (saturate(delta_cmd, delta_max) - delta) / tau_servo
    return (*d, V * math.cos(th), -V * math.sin(th), servo)
