"""Linear analysis of the glider loops (``glider-cosim analyze``).

Uses the pure models directly (no FMI): the equilibrium, the paper's time-scale
constants (Sec. 2.2), open- and closed-loop eigenvalues of the full model with the
passivity law (continuous time, full-state feedback), the paper's reduced-model test
(Sec. 3.2: A22 and the Schur complement of the nondimensional Jacobian), the sampled-data
loop at the communication step with the servo (the one-step map linearised by central
differences, with and without observer and pre-filter), the observer's gain and error
dynamics, and the stable ranges of K_c for each loop.

With a plant FMU (``--from-fmu``, :func:`fmu_plant_jacobian`) the continuous-time
Jacobian is the FMU's own, from its directional derivatives at the equilibrium
(:mod:`glider_cosim.studies.linearize`) with the passivity law's exact gradient, instead
of central differences of the model: the open- and closed-loop eigenvalues, the
reduced-model test and the continuous stable K_c come from the FMU.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from glider_controller.laws import passivity_law
from glider_observer.filter import butterworth_coefficients
from glider_observer.model import (
    C_O,
    DEFAULT_Q,
    DEFAULT_R,
    linearization,
    observer_gain,
    observer_step,
)
from glider_plant.model import derivatives, equilibrium, plant_step
from glider_plant.params import GliderParams

K_C_LIST = (1.0, 2.0, 3.0, 5.0, 6.0, 8.0, 10.0, 15.0, 20.0)
_BIG = 1e3  # delta_max large enough that the law never saturates near the equilibrium
_EPS = 1e-7


def _jacobian(f: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, eps: float = _EPS):
    """Central-difference Jacobian of ``f`` at ``x0``."""
    n = len(x0)
    J = np.empty((len(f(x0)), n))
    for i in range(n):
        d = np.zeros(n)
        d[i] = eps * max(1.0, abs(x0[i]))
        J[:, i] = (f(x0 + d) - f(x0 - d)) / (2 * d[i])
    return J


def time_scales(p: GliderParams) -> dict[str, float]:
    """tau_s [s], eps1, eps2, mu of the nondimensional model (paper Sec. 2.2)."""
    e = equilibrium(p)
    tau_s = p.m / (e.K_De * e.V)
    eps2 = -p.J2 / (p.K_q * e.V**2) / tau_s
    eps1 = (p.K_q / p.K_M) / tau_s
    return {"tau_s": tau_s, "eps1": eps1, "eps2": eps2, "mu": max(eps1, eps2)}


#: the body's Jacobian at the equilibrium from elsewhere (an FMU): p -> (A, b), A 4 x 4
#: over (V, theta_g, alpha, omega2) [1/s and the like], b the column of the tail angle
PlantJacobian = Callable[[GliderParams], tuple[np.ndarray, np.ndarray]]


def fmu_plant_jacobian(fmu: Path | str) -> PlantJacobian:
    """The body's Jacobian at the equilibrium from the plant FMU's directional derivatives
    (:func:`glider_cosim.studies.linearize.linearize`, the FMU's parameters set to ``p``
    and its initial state to the equilibrium; once per parameter set).
    ``.residual(p)``: the largest |state derivative| the FMU reports there (0 at an exact
    equilibrium)."""
    from .linearize import linearize

    done: dict[tuple, Any] = {}

    def lin(p: GliderParams) -> Any:
        key = tuple(p.as_dict().items())
        if key not in done:
            e = equilibrium(p)
            start = {**p.as_dict(), "V_0": e.V, "theta_g_0": e.theta_g, "alpha_0": e.alpha,
                     "omega2_0": 0.0, "delta_0": 0.0}  # fmt: skip
            done[key] = linearize(fmu, start)
        return done[key]

    def jacobian(p: GliderParams) -> tuple[np.ndarray, np.ndarray]:
        L = lin(p)
        body = [L.states.index(n) for n in ("V", "theta_g", "alpha", "omega2")]
        return L.A[np.ix_(body, body)], L.A[body, L.states.index("delta")]

    jacobian.residual = lambda p: float(np.max(np.abs(lin(p).derivatives[:4])))  # type: ignore[attr-defined]
    return jacobian


def _law_gradient(p: GliderParams, K_c: float) -> np.ndarray:
    """d delta_cmd / d(V, theta_g, alpha, omega2) of the passivity law at the equilibrium
    (unsaturated): there y_r = 0, dy_r/dV = 2 k sin(alpha_e) / V_e, dy_r/dtheta_g =
    k cos(alpha_e) with k = K_Fdelta / K_De, and d delta/dy_r = -1 / (K_c K_udelta)."""
    e = equilibrium(p)
    k = p.K_Fdelta / e.K_De
    dy = np.array([2.0 * k * math.sin(e.alpha) / e.V, k * math.cos(e.alpha), 0.0, 0.0])
    return -dy / (K_c * p.K_udelta)


def closed_loop_matrix(
    p: GliderParams, K_c: float | None, jacobian: PlantJacobian | None = None
) -> np.ndarray:
    """Jacobian [1/s] of Eqs. (6)-(9) at the equilibrium, with the passivity law on the
    true state (``K_c=None``: open loop, ``u_delta = 0``); by central differences of the
    model, or from ``jacobian`` (e.g. :func:`fmu_plant_jacobian`)."""
    if jacobian is not None:
        A, b = jacobian(p)
        return A.copy() if K_c is None else A + np.outer(b, _law_gradient(p, K_c))
    e = equilibrium(p)

    def f(x):
        u = 0.0 if K_c is None else p.K_udelta * passivity_law(x[0], x[1], K_c, p, e, _BIG)
        return np.array(derivatives(0.0, tuple(x), u, p))

    return _jacobian(f, np.array([e.V, e.theta_g, e.alpha, 0.0]))


def reduced_model_test(
    p: GliderParams, K_c: float, jacobian: PlantJacobian | None = None
) -> dict[str, Any]:
    """The paper's Sec. 3.2 test on the nondimensional closed-loop Jacobian.

    States (Vbar, thbar | alphabar, omegabar), time t/tau_s. A22 (fast block) and the
    Schur complement A11 - A12 A22^-1 A21 must both be Hurwitz; the test is conclusive
    only for sufficiently small mu.
    """
    e = equilibrium(p)
    ts = time_scales(p)
    T = np.diag([1.0 / e.V, 1.0, 1.0, p.K_q / p.K_M])
    A = ts["tau_s"] * T @ closed_loop_matrix(p, K_c, jacobian) @ np.linalg.inv(T)
    A11, A12, A21, A22 = A[:2, :2], A[:2, 2:], A[2:, :2], A[2:, 2:]
    S = A11 - A12 @ np.linalg.solve(A22, A21)
    ev22, evS = np.linalg.eigvals(A22), np.linalg.eigvals(S)
    m0g = p.m0 * p.g
    k = m0g / (e.K_De * e.V**2)
    return {
        "schur_matrix": S.tolist(),
        # the paper's dominant-term approximation of that matrix (Sec. 3.2)
        "paper_dominant_terms": [[-2.0, -k * math.cos(e.theta_g)],
                                 [k * math.cos(e.theta_g), k * math.sin(e.theta_g)]],
        "A22_eigenvalues": _cplx(ev22), "schur_eigenvalues": _cplx(evS),
        "A22_hurwitz": bool(np.all(ev22.real < 0)), "schur_hurwitz": bool(np.all(evS.real < 0)),
        "mu": ts["mu"], "full_nondimensional_eigenvalues": _cplx(np.linalg.eigvals(A)),
    }  # fmt: skip


def _filter_step(hist: Sequence[float], x: float, coef: Sequence[float]):
    a0, a1, a2, b1, b2 = coef
    x1, x2, y1, y2 = hist
    y = a0 * x + a1 * x1 + a2 * x2 - b1 * y1 - b2 * y2
    return y, (x, x1, y, y1)


def sampled_loop_map(
    p: GliderParams,
    K_c: float,
    h: float = 0.02,
    tau_servo: float = 0.01,
    observer: bool = False,
    R: float = DEFAULT_R,
    Q: Sequence[float] = DEFAULT_Q,
    f_cutoff: float = 10.0,
) -> tuple[Callable[[np.ndarray], np.ndarray], np.ndarray]:
    """One-step map of the sampled loop (the master's Gauss-Seidel semantics) and its
    fixed point. State: (V, theta_g, alpha, omega2, delta) and, with the observer, the
    estimate (4) and the pre-filter history (4)."""
    e = equilibrium(p)
    H = observer_gain(p, R, Q) if observer else None
    coef = butterworth_coefficients(1.0 / h, f_cutoff) if observer else None

    def step(s: np.ndarray) -> np.ndarray:
        x = (s[0], s[1], s[2], s[3], 0.0, 0.0)
        if observer:
            xh = tuple(s[5:9])
            theta_f, hist = _filter_step(s[9:13], s[1] + s[2], coef)
            cmd = passivity_law(xh[0], xh[1], K_c, p, e, _BIG)
            xh = observer_step(xh, theta_f, p.K_udelta * cmd, h, p, H)
        else:
            cmd = passivity_law(s[0], s[1], K_c, p, e, _BIG)
        x, d = plant_step(x, s[4], cmd, h, p, tau_servo)
        out = [x[0], x[1], x[2], x[3], d]
        if observer:
            out += [*xh, *hist]
        return np.array(out)

    th = e.theta_g + e.alpha
    fixed = [e.V, e.theta_g, e.alpha, 0.0, 0.0]
    if observer:
        fixed += [e.V, e.theta_g, e.alpha, 0.0, th, th, th, th]
    return step, np.array(fixed)


def sampled_loop_eigenvalues(p: GliderParams, K_c: float, **kw: Any) -> np.ndarray:
    """Eigenvalues (z-plane) of the linearised one-step map; stable iff all |z| < 1."""
    step, x0 = sampled_loop_map(p, K_c, **kw)
    return np.linalg.eigvals(_jacobian(step, x0, 1e-6))


def observer_analysis(
    p: GliderParams, R: float = DEFAULT_R, Q: Sequence[float] = DEFAULT_Q
) -> dict[str, Any]:
    """Observability of (A_o, C_o), the gain H_o and eig(A_o - H_o C_o)."""
    A = np.array(linearization(p))
    C = np.array([C_O])
    obs = np.vstack([C @ np.linalg.matrix_power(A, k) for k in range(4)])
    H = np.array(observer_gain(p, R, Q))
    ev = np.linalg.eigvals(A - H[:, None] @ C)
    return {"observability_rank": int(np.linalg.matrix_rank(obs)),
            "observable": bool(np.linalg.matrix_rank(obs) == 4), "H_o": [float(v) for v in H],
            "error_eigenvalues": _cplx(ev), "R": R, "Q": list(Q)}  # fmt: skip


def stable_kc_range(
    is_stable: Callable[[float], bool], k_min: float = 0.1, k_max: float = 1000.0, n: int = 80
) -> list[float | None]:
    """[low, high] of the stable K_c interval that reaches the largest gains (a large
    K_c means a weak law, stable when the open loop is); None = unbounded / none.
    Grid on a log scale, edges refined by bisection."""
    grid = np.geomspace(k_min, k_max, n)
    ok = [is_stable(k) for k in grid]
    if not ok[-1]:
        return [None, None] if not any(ok) else [float(grid[ok.index(True)]), None]
    i = len(ok) - 1
    while i > 0 and ok[i - 1]:
        i -= 1
    if i == 0:
        return [None, None]  # stable everywhere on the grid: [k_min, unbounded)
    lo, hi = grid[i - 1], grid[i]
    for _ in range(30):
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if is_stable(mid) else (mid, hi)
    return [float(hi), None]


def stable_kc_ranges(
    p: GliderParams, h: float = 0.02, tau_servo: float = 0.01,
    jacobian: PlantJacobian | None = None,
) -> dict[str, list[float | None]]:  # fmt: skip
    """Stable K_c ranges of the continuous loop and of the sampled loops."""

    def sampled(observer: bool) -> Callable[[float], bool]:
        return lambda k: bool(np.all(np.abs(sampled_loop_eigenvalues(
            p, k, h=h, tau_servo=tau_servo, observer=observer)) < 1))  # fmt: skip

    cont = lambda k: bool(np.all(np.linalg.eigvals(closed_loop_matrix(p, k, jacobian)).real < 0))  # noqa: E731
    return {"continuous": stable_kc_range(cont), "sampled": stable_kc_range(sampled(False)),
            "sampled_with_observer": stable_kc_range(sampled(True))}  # fmt: skip


def _cplx(ev: np.ndarray) -> list[list[float]]:
    return [[float(z.real), float(z.imag)] for z in sorted(ev, key=lambda z: (z.real, z.imag))]


#: the K_Fdelta values (N/rad) of the sensitivity study (Sec. 5: the CFD value's spread)
SENSITIVITY_K_FDELTA = (15.0, 29.5, 45.0)

#: the closed-loop table's columns, explained under it (``glider-cosim analyze``)
TABLE_LEGEND = (
    "K_c: the passivity law's gain; the law divides by it: a larger K_c is gentler",
    "cont. max Re: the largest real part of the continuous closed loop's eigenvalues, 1/s "
    "(stable below 0)",
    "A22: the reduced-model test of Sec. 3.2: the fast block (alpha, omega) of the "
    "nondimensional Jacobian is Hurwitz",
    "Schur: its slow block, the Schur complement A11 - A12 A22^-1 A21, is Hurwitz",
    "|z| sampled: the spectral radius of the loop sampled at h with the servo (stable below 1)",
    "|z| +observer: the same with the observer and its pre-filter in the loop",
)


def analyze(
    p: GliderParams | None = None,
    K_c_list: Sequence[float] = K_C_LIST,
    h: float = 0.02,
    tau_servo: float = 0.01,
    plant_fmu: Path | str | None = None,
) -> dict[str, Any]:
    """Everything ``glider-cosim analyze`` reports, as a JSON-serialisable dict (about 3 s:
    its steps shown on stderr, :mod:`glider_cosim.progress`: the closed loop at each
    gain, then the stable K_c ranges at each K_Fdelta, once each); with ``plant_fmu`` the
    continuous-time Jacobian is that FMU's (:func:`fmu_plant_jacobian`) and
    ``linearization`` says so."""
    from ..progress import Progress

    p = p or GliderParams()
    steps = 2 + sum(kf != p.K_Fdelta for kf in SENSITIVITY_K_FDELTA)
    with Progress(steps, "analyze") as bar:
        return _analyze(p, K_c_list, h, tau_servo, bar, plant_fmu)


def _analyze(
    p: GliderParams, K_c_list: Sequence[float], h: float, tau_servo: float, bar: Any,
    plant_fmu: Path | str | None,
) -> dict[str, Any]:  # fmt: skip
    e = equilibrium(p)
    jac = fmu_plant_jacobian(plant_fmu) if plant_fmu is not None else None
    per_kc = []
    bar.step(f"analyze: the closed loop at {len(K_c_list)} gains K_c")
    for k in K_c_list:
        ev = np.linalg.eigvals(closed_loop_matrix(p, k, jac))
        zs = sampled_loop_eigenvalues(p, k, h=h, tau_servo=tau_servo)
        zo = sampled_loop_eigenvalues(p, k, h=h, tau_servo=tau_servo, observer=True)
        per_kc.append({
            "K_c": k,
            "continuous_eigenvalues": _cplx(ev),
            "continuous_max_real": float(ev.real.max()),
            "continuous_stable": bool(ev.real.max() < 0),
            "reduced_model_test": reduced_model_test(p, k, jac),
            "sampled_spectral_radius": float(np.abs(zs).max()),
            "sampled_with_observer_spectral_radius": float(np.abs(zo).max()),
        })  # fmt: skip
    bar.step(f"analyze: the stable K_c ranges at K_Fdelta = {p.K_Fdelta:g} (the model's)")
    ours = stable_kc_ranges(p, h, tau_servo, jac)
    sens = {}
    for kf in SENSITIVITY_K_FDELTA:  # the model's value is not computed again
        if kf != p.K_Fdelta:
            bar.step(f"analyze: the stable K_c ranges at K_Fdelta = {kf:g}")
        pk = GliderParams(**{**p.as_dict(), "K_Fdelta": kf})
        r = ours if kf == p.K_Fdelta else stable_kc_ranges(pk, h, tau_servo, jac)
        sens[f"{kf:g}"] = {"continuous": r["continuous"], "sampled": r["sampled"]}
    ol = np.linalg.eigvals(closed_loop_matrix(p, None, jac))
    source = {} if jac is None else {"linearization": {
        "plant_fmu": str(plant_fmu), "residual": jac.residual(p)}}  # fmt: skip
    return {
        "equilibrium": {"V": e.V, "theta_g": e.theta_g, "alpha": e.alpha, "omega2": e.omega2},
        "time_scales": time_scales(p),
        "open_loop_eigenvalues": _cplx(ol),
        "closed_loop": per_kc,
        "observer": observer_analysis(p),
        "stable_K_c": ours,
        "K_Fdelta_sensitivity": sens,
        "settings": {"h": h, "tau_servo": tau_servo, "K_Fdelta": p.K_Fdelta},
        **source,
    }


def _fmt_range(r: Sequence[float | None]) -> str:
    lo, hi = r
    if lo is None and hi is None:
        return "none found"
    return f"K_c > {lo:.3f}" if hi is None else f"{lo:.3f} < K_c < {hi:.3f}"


def format_report(a: dict[str, Any]) -> str:
    """Human-readable summary of :func:`analyze`'s result."""
    eq, ts = a["equilibrium"], a["time_scales"]
    deg = 180.0 / math.pi
    out = [
        f"equilibrium: V = {eq['V']:.5f} m/s, theta_g = {eq['theta_g'] * deg:.3f} deg, "
        f"alpha = {eq['alpha'] * deg:.3f} deg, omega2 = 0",
        f"time scales: tau_s = {ts['tau_s']:.4g} s, eps1 = {ts['eps1']:.4g}, "
        f"eps2 = {ts['eps2']:.4g}, mu = {ts['mu']:.4g} (dimensionless)",
        "open-loop eigenvalues [1/s]: "
        + ", ".join(f"{re:.4f}{im:+.4f}j" for re, im in a["open_loop_eigenvalues"]),
        *(
            [
                f"linearization: the plant FMU's directional derivatives ({lin['plant_fmu']}), "
                f"its state derivatives at the equilibrium <= {lin['residual']:.1e}"
            ]
            if (lin := a.get("linearization"))
            else []
        ),  # fmt: skip
        "",
        f"{'K_c':>6} {'cont. max Re':>13} {'A22':>5} {'Schur':>6} {'|z| sampled':>12} "
        f"{'|z| +observer':>14}",
    ]
    for c in a["closed_loop"]:
        rt = c["reduced_model_test"]
        out.append(
            f"{c['K_c']:6g} {c['continuous_max_real']:13.4f} "
            f"{'ok' if rt['A22_hurwitz'] else 'no':>5} {'ok' if rt['schur_hurwitz'] else 'no':>6} "
            f"{c['sampled_spectral_radius']:12.5f} "
            f"{c['sampled_with_observer_spectral_radius']:14.5f}"
        )
    out += ["", "columns:", *(f"  {line}" for line in TABLE_LEGEND)]
    o = a["observer"]
    out += [
        "",
        f"observer: rank of the observability matrix {o['observability_rank']}, "
        f"H_o = [{', '.join(f'{v:.4f}' for v in o['H_o'])}], "
        "eig(A_o - H_o C_o) = "
        + ", ".join(f"{re:.3f}{im:+.3f}j" for re, im in o["error_eigenvalues"]),
        "",
        "stable K_c: " + "; ".join(f"{k}: {_fmt_range(v)}" for k, v in a["stable_K_c"].items()),
        "K_Fdelta sensitivity: "
        + "; ".join(
            f"K_Fdelta = {k}: continuous {_fmt_range(v['continuous'])}, sampled "
            f"{_fmt_range(v['sampled'])}"
            for k, v in a["K_Fdelta_sensitivity"].items()
        ),
    ]
    return "\n".join(out)
