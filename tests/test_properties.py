"""Property-based tests (hypothesis): random parameter sets, initial states and
disturbances inside the physical envelope give finite results or a clean, named stall;
draws outside the envelope are refused with a ParameterError."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from glider_controller.laws import passivity_law
from glider_observer.model import DEFAULT_Q, DEFAULT_R, observer_gain, observer_step
from glider_plant.model import StallError, equilibrium, plant_step
from glider_plant.params import MODEL_CONSTANTS, GliderParams, ParameterError

NOMINAL = {s.name: s.default for s in MODEL_CONSTANTS}


def scaled(name: str, lo: float = 0.8, hi: float = 1.2):
    v = NOMINAL[name]
    return st.floats(min(v * lo, v * hi), max(v * lo, v * hi), allow_nan=False)


params = st.builds(
    GliderParams,
    m=scaled("m"),
    J2=scaled("J2"),
    K_L=scaled("K_L"),
    K_D0=scaled("K_D0"),
    K_D=scaled("K_D"),
    K_q=scaled("K_q"),
    K_M0=scaled("K_M0"),
    K_M=scaled("K_M"),
    K_Fdelta=scaled("K_Fdelta", 0.5, 1.5),
    m0=scaled("m0", 0.5, 2.0),
)
states = st.tuples(
    st.floats(0.1, 0.4),  # V, m/s
    st.floats(math.radians(-60), math.radians(-5)),  # theta_g
    st.floats(math.radians(-5), math.radians(10)),  # alpha
    st.floats(-0.5, 0.5),  # omega2
)
disturbances = st.tuples(st.floats(-0.2, 0.2), st.floats(-0.2, 0.2), st.floats(-0.02, 0.02))


@settings(max_examples=60, deadline=None)
@given(p=params, x0=states, dist=disturbances, K_c=st.floats(1.0, 50.0))
def test_closed_loop_is_finite_or_stalls_cleanly(p, x0, dist, K_c):
    e = equilibrium(p)
    H = observer_gain(p, DEFAULT_R, DEFAULT_Q)
    x = (*x0, 0.0, 0.0)
    xh = (e.V, e.theta_g, e.alpha, 0.0)
    d = 0.0
    try:
        for k in range(500):  # 10 s at 50 Hz
            cmd = passivity_law(xh[0], xh[1], K_c, p, e, math.pi / 2)
            xh = observer_step(xh, x[1] + x[2], cmd, 0.02, p, H)
            x, d = plant_step(x, d, cmd, 0.02, p, 0.01, dist if 100 <= k < 150 else (0, 0, 0))
    except StallError as err:
        assert "glider stalled: V = " in str(err)
        return
    assert all(math.isfinite(v) for v in (*x, *xh, d))
    assert x[0] > 0


@settings(max_examples=40, deadline=None)
@given(
    name=st.sampled_from([s.name for s in MODEL_CONSTANTS if s.valid.low is not None
                          or s.valid.high is not None]),
    value=st.one_of(st.just(float("nan")), st.just(float("inf")), st.floats(-1e3, 1e3)),
)  # fmt: skip
def test_out_of_envelope_draws_are_refused(name, value):
    spec = next(s for s in MODEL_CONSTANTS if s.name == name)
    try:
        GliderParams(**{name: value})
    except ParameterError as err:
        assert not spec.valid.contains(value) or "K_L0 + K_L*alpha_e" in str(err)
        assert str(err).startswith(name) or "K_L0 + K_L*alpha_e" in str(err)
    else:
        assert spec.valid.contains(value)
