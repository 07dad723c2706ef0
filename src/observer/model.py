"""Nonlinear observer of the glider state from pitch alone (paper Sec. 4, Eqs. (34)-(37)).

``d(x_hat)/dt = f(x_hat, u_delta) + H_o (theta - h(x_hat))`` with ``h(x) = theta_g + alpha``
and the constant gain ``H_o = P C_o^T / R`` from the Riccati equation (36) at the
open-loop equilibrium.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from glider_observer.riccati import RiccatiError, solve_filter_care
from glider_plant.model import Equilibrium, State4, check_state, constants, equilibrium, rhs
from glider_plant.params import GliderParams, ParameterError

C_O = (0.0, 1.0, 1.0, 0.0)
#: Riccati weights: R is the paper's measurement variance (Sec. 4); Q is not given in the
#: paper, 0.1 on every state gives an estimate within 1 deg after 1 s from the Sec. 3.3 start.
DEFAULT_R = 0.1
DEFAULT_Q = (0.1, 0.1, 0.1, 0.1)


def linearization(p: GliderParams, eq: Equilibrium | None = None) -> list[list[float]]:
    """Observer matrix ``A_o`` of Sec. 4 (Jacobian of Eqs. (6)-(9) at the equilibrium).

    Returns
    -------
    list of 4 lists of 4 floats
        ``A_o`` in SI units (1/s).
    """
    e = eq or equilibrium(p)
    V, th, al = e.V, e.theta_g, e.alpha
    m, J2 = p.m, p.J2
    dD_dV = 2.0 * V * (p.K_D0 + p.K_D * al * al)
    dD_da = 2.0 * p.K_D * V * V * al
    dL_dV = 2.0 * V * (p.K_L0 + p.K_L * al)
    dL_da = p.K_L * V * V
    m0g = p.m0 * p.g
    return [
        [-dD_dV / m, -m0g * math.cos(th) / m, -dD_da / m, 0.0],
        [dL_dV / (m * V), m0g * math.sin(th) / (m * V), dL_da / (m * V), 0.0],
        [-dL_dV / (m * V), -m0g * math.sin(th) / (m * V), -dL_da / (m * V), 1.0],
        [2.0 * V * (p.K_M0 + p.K_M * al) / J2, 0.0, p.K_M * V * V / J2, p.K_q * V * V / J2],
    ]


def observer_gain(
    p: GliderParams, R: float, Q: Sequence[float]
) -> tuple[float, float, float, float]:
    """Gain ``H_o`` of Eq. (37) from the Riccati equation (36).

    Parameters
    ----------
    p : GliderParams
        The observer's model constants.
    R : float
        Measurement-noise variance, rad^2 (> 0).
    Q : sequence of 4 floats
        Diagonal of the process-noise covariance (each > 0).

    Returns
    -------
    tuple of 4 floats
        ``H_o`` (units 1/s per rad of output error, per state).
    """
    if not (math.isfinite(R) and R > 0.0):
        raise ParameterError(f"R = {R!r} is invalid: expected a finite value > 0")
    for name, q in zip(("Q_V", "Q_theta_g", "Q_alpha", "Q_omega2"), Q):
        if not (math.isfinite(q) and q > 0.0):
            raise ParameterError(f"{name} = {q!r} is invalid: expected a finite value > 0")
    P = riccati_solution(p, R, Q)
    H = []
    for i in range(4):
        s = 0.0
        for j in range(4):
            s += P[i][j] * C_O[j]
        H.append(s / R)
    return (H[0], H[1], H[2], H[3])


def riccati_solution(p: GliderParams, R: float, Q: Sequence[float]) -> list[list[float]]:
    """``P`` of Eq. (36): ``A P + P A^T + Q - P C^T R^-1 C P = 0`` (R, Q already checked).

    Pure Python (:mod:`glider_observer.riccati`); ``observer_model.c`` computes the same bits.
    """
    A = linearization(p)
    Qm = [[float(Q[i]) if i == j else 0.0 for j in range(4)] for i in range(4)]
    G = [[C_O[i] * C_O[j] / R for j in range(4)] for i in range(4)]
    try:
        return solve_filter_care(A, Qm, G)
    except RiccatiError as err:
        raise RiccatiError(
            f"observer gain for R = {R!r}, Q = ({Q[0]!r}, {Q[1]!r}, {Q[2]!r}, {Q[3]!r}): {err}"
        ) from None


def observer_step(
    xh: State4,
    theta: float,
    u_delta: float,
    h: float,
    p: GliderParams,
    H: Sequence[float],
    h_max: float = 0.02,
) -> State4:
    """Integrate Eq. (34) over one step with ``theta`` and ``u_delta`` held (RK4).

    Parameters
    ----------
    xh : tuple of 4 floats
        Estimate ``(V, theta_g, alpha, omega2)`` at the start of the step.
    theta : float
        (Filtered) measured pitch, rad.
    u_delta : float
        Effective control input, rad.
    h : float
        Step, s.
    p : GliderParams
        The observer's model constants.
    H : sequence of 4 floats
        Observer gain ``H_o``.
    h_max : float
        Largest RK4 sub-step, s.

    Raises
    ------
    glider_plant.model.StallError
        If the estimated speed falls to zero or the estimate is not finite.
    """
    n = max(1, math.ceil(h / h_max - 1e-9))
    dt = h / n
    h0, h1, h2, h3 = H

    consts = constants(p)

    def f(x: State4) -> State4:
        d = rhs(x[0], x[1], x[2], x[3], u_delta, consts)
        e = theta - x[1] - x[2]
        return (d[0] + h0 * e, d[1] + h1 * e, d[2] + h2 * e, d[3] + h3 * e)

    V, th, al, w = xh
    for _ in range(n):
        k1 = f((V, th, al, w))
        k2 = f(
            (
                V + 0.5 * dt * k1[0],
                th + 0.5 * dt * k1[1],
                al + 0.5 * dt * k1[2],
                w + 0.5 * dt * k1[3],
            )
        )
        k3 = f(
            (
                V + 0.5 * dt * k2[0],
                th + 0.5 * dt * k2[1],
                al + 0.5 * dt * k2[2],
                w + 0.5 * dt * k2[3],
            )
        )
        k4 = f((V + dt * k3[0], th + dt * k3[1], al + dt * k3[2], w + dt * k3[3]))
        c = dt / 6.0
        V += c * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
        th += c * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
        al += c * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
        w += c * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3])
        check_state((V, th, al, w))
    return (V, th, al, w)
