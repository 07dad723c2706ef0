"""Pure-model tests of the plant: equilibrium, dynamics, integrator, servo, sensor."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from glider_plant.jacobian import plant_derivatives, plant_jacobian
from glider_plant.model import (
    PitchSensor,
    StallError,
    derivatives,
    equilibrium,
    plant_step,
    servo_response,
)
from glider_plant.params import GliderParams, ParameterError

P = GliderParams()
X0 = (0.2, math.radians(-35.0), math.radians(1.0), 0.0)


def test_equilibrium_against_paper_band():
    e = equilibrium(P)
    # paper Sec. 3.3: V_e = 0.24 m/s, theta_ge = -22.5 deg, alpha_e = 1.52 deg (rounded)
    assert e.V == pytest.approx(0.24, abs=0.005)
    assert math.degrees(e.theta_g) == pytest.approx(-22.5, rel=0.01)
    assert math.degrees(e.alpha) == pytest.approx(1.52, abs=0.005)
    assert e.omega2 == 0.0
    # closed form digits (our reference)
    assert e.V == pytest.approx(0.2371273, abs=1e-7)
    assert e.theta_g == pytest.approx(-0.3940433, abs=1e-7)


def test_equilibrium_is_a_fixed_point():
    e = equilibrium(P)
    f = derivatives(0.0, (e.V, e.theta_g, e.alpha, 0.0), 0.0, P)
    assert max(map(abs, f)) < 1e-12


def test_disturbance_force_along_velocity_slows_the_glider():
    e = equilibrium(P)
    x = (e.V, e.theta_g, e.alpha, 0.0)
    # a force opposing the velocity (velocity points forward and down)
    fx, fz = -math.cos(e.theta_g), math.sin(e.theta_g)
    dV = derivatives(0.0, x, 0.0, P, F_x=fx, F_z=fz)[0]
    assert dV == pytest.approx(-1.0 / P.m, rel=1e-12)
    assert derivatives(0.0, x, 0.0, P, M_y=0.08)[3] == pytest.approx(1.0, rel=1e-12)


def _reference(delta_cmd: float, tau: float, t_end: float):
    """Body + servo + kinematics with solve_ivp at tight tolerance."""

    def rhs(t, y):
        d = derivatives(t, tuple(y[:4]), P.K_udelta * y[4], P)
        return [*d, (delta_cmd - y[4]) / tau, y[0] * math.cos(y[1]), -y[0] * math.sin(y[1])]

    return solve_ivp(
        rhs,
        (0, t_end),
        [*X0, 0.0, 0.0, 0.0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        dense_output=True,
    )


@pytest.mark.parametrize("h", [0.02, 0.05, 0.1])
def test_plant_step_matches_solve_ivp_with_servo(h):
    cmd, tau = math.radians(10.0), 0.01
    ref = _reference(cmd, tau, 20.0)
    x, d = (*X0, 0.0, 0.0), 0.0
    worst = 0.0
    for k in range(round(20.0 / h)):
        x, d = plant_step(x, d, cmd, h, P, tau)
        y = ref.sol((k + 1) * h)
        worst = max(worst, abs(x[1] - y[1]), abs(d - y[4]), abs(x[5] - y[6]))
    assert worst < 1e-6


def test_servo_exact_exponential():
    assert servo_response(0.0, 1.0, 0.01, 0.01) == pytest.approx(1 - math.exp(-1), rel=1e-15)
    assert servo_response(0.3, 0.3, 0.01, 5.0) == 0.3


def test_stall_is_reported():
    x = (0.002, 0.0, 0.0, 0.0, 0.0, 0.0)
    with pytest.raises(StallError, match=r"glider stalled: V = .* m/s"):
        plant_step(x, 0.0, 0.0, 0.5, P, 0.01, disturbance=(-50.0, 0.0, 0.0))


def test_sensor_is_seeded_and_has_the_requested_spread():
    a = PitchSensor(0.1, seed=3)
    b = PitchSensor(0.1, seed=3)
    c = PitchSensor(0.1, seed=4)
    sa = [a.measure(0.0) for _ in range(4000)]
    assert sa == [b.measure(0.0) for _ in range(4000)]
    assert sa[:10] != [c.measure(0.0) for _ in range(10)]
    assert statistics.pstdev(sa) == pytest.approx(0.1, rel=0.05)
    assert abs(statistics.fmean(sa)) < 0.01
    state = a.get_state()
    nxt = [a.measure(0.0) for _ in range(3)]
    a.set_state(state)
    assert [a.measure(0.0) for _ in range(3)] == nxt
    assert PitchSensor(0.0).measure(0.25) == 0.25


@pytest.mark.parametrize(
    ("name", "value", "expected"),
    [
        ("m", -1.0, r"m = -1.0 is invalid: expected a finite value in \(0, inf\)"),
        ("J2", 0.0, r"J2 = 0.0 is invalid: expected a finite value in \(0, inf\)"),
        ("K_q", float("nan"), r"K_q = nan is invalid"),
        ("m0", float("inf"), r"m0 = inf is invalid"),
        ("K_M", 1.0, r"K_M = 1.0 is invalid: expected a finite value in \(-inf, 0\)"),
    ],
)
def test_invalid_parameters_are_refused(name, value, expected):
    with pytest.raises(ParameterError, match=expected):
        GliderParams(**{name: value})


def test_params_round_trip():
    p = GliderParams.from_mapping({"m": 12.0, "unrelated": 1})
    assert p.m == 12.0 and p.as_dict()["K_L"] == 303.6
    assert np.isclose(equilibrium(p).V, equilibrium(P).V)  # V_e does not depend on m


def _random_points(n: int, seed: int):
    """(state, delta, delta_cmd, disturbance, params) spread over the model's range, the
    command on both sides of the tail limit 0.9 rad."""
    rng = np.random.default_rng(seed)
    params = (P, GliderParams(m=12.0, J2=0.1), GliderParams(K_q=-0.3, m0=0.2, K_L=250.0))
    for k in range(n):
        x = (rng.uniform(0.05, 1.0), rng.uniform(-1.5, 1.5), rng.uniform(-0.5, 0.5),
             rng.uniform(-2, 2), rng.uniform(-5, 5), rng.uniform(-5, 5))  # fmt: skip
        dist = tuple(rng.uniform(-1, 1, 3) * (1.0, 1.0, 0.1)) if k % 2 else (0.0, 0.0, 0.0)
        yield x, rng.uniform(-0.5, 0.5), rng.uniform(-1.2, 1.2), dist, params[k % 3]


def test_plant_jacobian_matches_central_differences():
    """Every entry of the analytic Jacobian (8 x 11) against central differences of
    plant_derivatives and of the pitch, to 1e-6 relative (1e-6 absolute near 0)."""
    tau, dmax = 0.01, 0.9
    worst = 0.0
    for x, delta, cmd, dist, p in _random_points(200, 3):
        if abs(abs(cmd) - dmax) < 1e-3:
            continue  # the saturation's kink: no derivative there

        def f(z, p=p):
            d = plant_derivatives(tuple(z[:6]), z[6], z[7], tuple(z[8:]), p, tau, dmax)
            return np.array([*d, z[1] + z[2]])

        z0 = np.array([*x, delta, cmd, *dist])
        J = np.array(plant_jacobian(x, delta, cmd, dist, p, tau, dmax))
        assert J.shape == (8, 11)
        for i in range(11):
            h = 1e-6 * max(1.0, abs(z0[i]))
            e = np.zeros(11)
            e[i] = h
            fd = (f(z0 + e) - f(z0 - e)) / (2 * h)
            worst = max(worst, float(np.max(np.abs(fd - J[:, i]) / np.maximum(1.0, np.abs(fd)))))
    assert worst < 1e-6


def test_plant_jacobian_at_the_equilibrium_is_the_observers_matrix():
    """The observer's A_o (its own closed form, Sec. 4) is the plant Jacobian's body block at
    the equilibrium with the tail at zero, to rounding."""
    from glider_observer.model import linearization

    for p in (P, GliderParams(m=12.0, J2=0.1)):
        e = equilibrium(p)
        J = np.array(plant_jacobian((e.V, e.theta_g, e.alpha, 0.0, 0.0, 0.0), 0.0, 0.0,
                                    (0.0, 0.0, 0.0), p, 0.01, 1.0))  # fmt: skip
        np.testing.assert_allclose(J[:4, :4], np.array(linearization(p)), rtol=1e-12, atol=1e-14)
        # the derivatives vanish there (a steady glide), the kinematics do not
        d = plant_derivatives((e.V, e.theta_g, e.alpha, 0.0, 0.0, 0.0), 0.0, 0.0,
                              (0.0, 0.0, 0.0), p, 0.01, 1.0)  # fmt: skip
        assert np.max(np.abs(d[:4])) < 1e-14 and d[6] == 0.0 and d[4] > 0.0


def test_the_slaves_derivative_dependencies_are_the_jacobians_nonzeros():
    """Each state derivative's declared dependencies (the FMUs' <Derivatives>) are exactly
    the columns where plant_jacobian is nonzero at generic points."""
    from glider_plant.jacobian import PLANT_INPUTS, PLANT_STATES
    from glider_plant.slave import GliderPlant

    names = PLANT_STATES + PLANT_INPUTS
    seen = np.zeros((7, 11), dtype=bool)
    for x, delta, cmd, dist, p in _random_points(50, 5):
        if abs(cmd) < 0.9 and all(dist):  # inside the tail limit, every disturbance on
            seen |= np.array(plant_jacobian(x, delta, cmd, dist, p, 0.01, 0.9))[:7] != 0.0
    for i, state in enumerate(PLANT_STATES):
        declared = GliderPlant.DERIVATIVE_DEPENDENCIES[f"der({state})"]
        assert {names[j] for j in np.flatnonzero(seen[i])} == set(declared), state
