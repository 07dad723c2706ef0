"""Sagittal-plane glider dynamics (paper Eqs. (1)-(9)), kinematics, servo, sensor.

State ``x = (V, theta_g, alpha, omega2)`` in m/s, rad, rad, rad/s; the plant adds
the kinematic states ``(x, z)`` in m (z = depth, positive down). Everything is in
plain floats: these functions sit on the ``doStep`` hot path.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from .params import GliderParams, ParameterError

State4 = tuple[float, float, float, float]
State6 = tuple[float, float, float, float, float, float]

#: Below this speed (m/s) the model is stalled: Eq. (7) divides by V.
V_STALL = 1e-3


#: Servo deviation (rad) up to which an RK4 sub-step of one servo time constant keeps the
#: glide-angle error of a command jump below 1e-8 rad (measured against solve_ivp at
#: 1e-12 tolerance: 2.4e-7 rad for a 10 deg jump at dt = tau); larger jumps shorten the
#: sub-steps by (ref/|deviation|)^(1/4), RK4 being 4th order.
SERVO_DEVIATION_REF = 7e-3


class StallError(ArithmeticError):
    """The glider stalled: speed fell to ``V_STALL`` or the state became non-finite."""


@dataclass(frozen=True)
class Equilibrium:
    """Open-loop steady glide (paper Sec. 2.1), SI units."""

    V: float
    theta_g: float
    alpha: float
    omega2: float
    K_De: float
    K_Le: float


def equilibrium(p: GliderParams) -> Equilibrium:
    """Closed-form steady glide with ``u_delta = 0`` (paper Sec. 2.1).

    Parameters
    ----------
    p : GliderParams
        Model constants.

    Returns
    -------
    Equilibrium
        ``V`` (m/s), ``theta_g`` (rad), ``alpha`` (rad), ``omega2`` (rad/s) and the
        effective coefficients ``K_De``, ``K_Le`` (kg/m).
    """
    alpha_e = -p.K_M0 / p.K_M
    k_de = p.K_D0 + p.K_D * alpha_e**2
    k_le = p.K_L0 + p.K_L * alpha_e
    theta_ge = math.atan(-k_de / k_le)
    v_e = math.sqrt(abs(p.m0) * p.g / math.hypot(k_de, k_le))
    return Equilibrium(v_e, theta_ge, alpha_e, 0.0, k_de, k_le)


def derivatives(
    t: float,
    x: State4,
    u_delta: float,
    p: GliderParams,
    F_x: float = 0.0,
    F_z: float = 0.0,
    M_y: float = 0.0,
) -> State4:
    """Right-hand side of Eqs. (6)-(9) with optional external disturbances.

    Parameters
    ----------
    t : float
        Time in s (unused; the model is autonomous).
    x : tuple of 4 floats
        ``(V, theta_g, alpha, omega2)`` in m/s, rad, rad, rad/s.
    u_delta : float
        Effective control-surface angle of attack, rad (``K_udelta * delta``).
    p : GliderParams
        Model constants.
    F_x, F_z : float
        Disturbance force in N, inertial frame (x forward-horizontal, z down).
    M_y : float
        Disturbance pitch moment in N m (nose up positive).

    Returns
    -------
    tuple of 4 floats
        ``(dV/dt, dtheta_g/dt, dalpha/dt, domega2/dt)``.
    """
    return rhs(x[0], x[1], x[2], x[3], u_delta, constants(p), F_x, F_z, M_y)


Constants = tuple[float, float, float, float, float, float, float, float, float, float, float]


def constants(p: GliderParams) -> Constants:
    """The constants :func:`rhs` needs, looked up once (the hot path avoids attribute access)."""
    return (p.m, p.J2, p.K_L0, p.K_L, p.K_D0, p.K_D, p.K_q, p.K_M0, p.K_M, p.K_Fdelta,
            p.m0 * p.g)  # fmt: skip


def rhs(
    V: float, th: float, al: float, w: float, u_delta: float, c: Constants,
    F_x: float = 0.0, F_z: float = 0.0, M_y: float = 0.0,
) -> State4:  # fmt: skip
    """Eqs. (6)-(9) on scalars with :func:`constants`; :func:`derivatives` documents it."""
    m, J2, K_L0, K_L, K_D0, K_D, K_q, K_M0, K_M, K_Fdelta, m0g = c
    V2 = V * V
    s_th = math.sin(th)
    c_th = math.cos(th)
    lift = (K_L0 + K_L * al) * V2
    drag = (K_D0 + K_D * al * al) * V2
    f_delta = K_Fdelta * V2 * u_delta
    # disturbance force along the velocity and along its upward normal
    f_v = F_x * c_th - F_z * s_th
    f_n = -F_x * s_th - F_z * c_th
    dV = (-m0g * s_th - drag + f_delta * math.sin(al) + f_v) / m
    dth = (-m0g * c_th + lift + f_delta * math.cos(al) + f_n) / (m * V)
    dw = ((K_M0 + K_M * al + K_q * w - K_M * u_delta) * V2 + M_y) / J2
    return (dV, dth, w - dth, dw)


def servo_response(delta0: float, command: float, tau: float, dt: float) -> float:
    """Exact response of the first-order tail servo to a held command.

    ``tau * d(delta)/dt = command - delta`` over ``dt`` seconds, from ``delta0`` (rad).
    """
    return command + (delta0 - command) * math.exp(-dt / tau)


def saturate(value: float, limit: float) -> float:
    """Clip ``value`` to ``[-limit, limit]``."""
    return limit if value > limit else (-limit if value < -limit else value)


def check_state(x: tuple[float, ...]) -> None:
    """Raise :class:`StallError` if the speed is below ``V_STALL`` or the state not finite."""
    V = x[0]
    if not V > V_STALL or not all(map(math.isfinite, x)):
        raise StallError(
            f"glider stalled: V = {V:.6g} m/s (model valid for V > {V_STALL:g} m/s, "
            "Eq. (7) divides by V)"
        )


def plant_step(
    x: State6,
    delta: float,
    delta_cmd: float,
    h: float,
    p: GliderParams,
    tau_servo: float,
    disturbance: tuple[float, float, float] = (0.0, 0.0, 0.0),
    h_max: float = 0.02,
) -> tuple[State6, float]:
    """Advance body, kinematics and servo over one communication step.

    Classical RK4 with ``ceil(h / h_max)`` equal sub-steps (more after a large command
    jump, see ``SERVO_DEVIATION_REF``); the servo angle inside the step is the exact
    exponential response to the held command, sampled so that RK4 integrates it exactly,
    so the 10 ms lag is integrated accurately for any ``h``.

    Parameters
    ----------
    x : tuple of 6 floats
        ``(V, theta_g, alpha, omega2, x, z)`` (m/s, rad, rad, rad/s, m, m).
    delta : float
        Actual tail angle at the start of the step, rad.
    delta_cmd : float
        Commanded tail angle, rad, already saturated; held over the step.
    h : float
        Step size, s.
    p : GliderParams
        Model constants.
    tau_servo : float
        Servo time constant, s.
    disturbance : tuple of 3 floats
        ``(F_x, F_z, M_y)`` held over the step (N, N, N m).
    h_max : float
        Largest RK4 sub-step, s.

    Returns
    -------
    (state, delta)
        State and tail angle at the end of the step.

    Raises
    ------
    StallError
        If the speed falls to ``V_STALL`` or the state becomes non-finite.
    """
    d0 = delta - delta_cmd  # servo deviation at the start of the step
    dt_max = h_max
    if abs(d0) > SERVO_DEVIATION_REF:
        # large command jumps: sub-steps short enough for the fast servo transient
        dt_max = min(h_max, tau_servo * (SERVO_DEVIATION_REF / abs(d0)) ** 0.25)
    n = max(1, math.ceil(h / dt_max - 1e-9))
    dt = h / n
    F_x, F_z, M_y = disturbance
    ku = p.K_udelta
    consts = constants(p)
    V, th, al, w, px, pz = x
    for i in range(n):
        s0 = i * dt
        e0 = math.exp(-s0 / tau_servo)
        e1 = math.exp(-(s0 + dt) / tau_servo)
        # mid-stage value chosen so that RK4's Simpson weights integrate the servo's
        # exponential exactly over the sub-step (the input is much faster than the body)
        eh = (6.0 * tau_servo / dt * (e0 - e1) - e0 - e1) / 4.0
        u0 = ku * (delta_cmd + d0 * e0)
        uh = ku * (delta_cmd + d0 * eh)
        u1 = ku * (delta_cmd + d0 * e1)
        k1 = rhs(V, th, al, w, u0, consts, F_x, F_z, M_y)
        x2 = (
            V + 0.5 * dt * k1[0],
            th + 0.5 * dt * k1[1],
            al + 0.5 * dt * k1[2],
            w + 0.5 * dt * k1[3],
        )
        k2 = rhs(x2[0], x2[1], x2[2], x2[3], uh, consts, F_x, F_z, M_y)
        x3 = (
            V + 0.5 * dt * k2[0],
            th + 0.5 * dt * k2[1],
            al + 0.5 * dt * k2[2],
            w + 0.5 * dt * k2[3],
        )
        k3 = rhs(x3[0], x3[1], x3[2], x3[3], uh, consts, F_x, F_z, M_y)
        x4 = (V + dt * k3[0], th + dt * k3[1], al + dt * k3[2], w + dt * k3[3])
        k4 = rhs(x4[0], x4[1], x4[2], x4[3], u1, consts, F_x, F_z, M_y)
        # kinematics: dx = V cos(theta_g), dz = -V sin(theta_g)
        kx = (
            V * math.cos(th)
            + 2.0 * x2[0] * math.cos(x2[1])
            + 2.0 * x3[0] * math.cos(x3[1])
            + x4[0] * math.cos(x4[1])
        )
        kz = (
            V * math.sin(th)
            + 2.0 * x2[0] * math.sin(x2[1])
            + 2.0 * x3[0] * math.sin(x3[1])
            + x4[0] * math.sin(x4[1])
        )
        c = dt / 6.0
        V += c * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
        th += c * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
        al += c * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
        w += c * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3])
        px += c * kx
        pz -= c * kz
        check_state((V, th, al, w, px, pz))
    return (V, th, al, w, px, pz), delta_cmd + d0 * math.exp(-h / tau_servo)


class PitchSensor:
    """Pitch measurement with zero-mean Gaussian noise from a seeded generator.

    Parameters
    ----------
    noise_std : float
        Standard deviation of the noise, rad (0 = noiseless).
    seed : int
        Seed of the generator; the same seed gives the same noise sequence.
    """

    def __init__(self, noise_std: float = 0.0, seed: int = 0) -> None:
        if not (math.isfinite(noise_std) and noise_std >= 0.0):
            raise ParameterError(
                f"noise_std = {noise_std!r} is invalid: expected a finite value >= 0"
            )
        self.noise_std = noise_std
        self._rng = random.Random(int(seed))

    def measure(self, theta: float) -> float:
        """Return ``theta`` plus one noise sample (rad)."""
        if self.noise_std == 0.0:
            return theta
        return theta + self._rng.gauss(0.0, self.noise_std)

    def get_state(self) -> list:
        """JSON-serialisable generator state."""
        version, internal, gauss_next = self._rng.getstate()
        return [version, list(internal), gauss_next]

    def set_state(self, state: list) -> None:
        version, internal, gauss_next = state
        self._rng.setstate((version, tuple(internal), gauss_next))
