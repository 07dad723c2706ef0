"""Property-based runs of the three FMUs under the master: random parameters, initial
states and disturbances inside the envelope end with finite rows or a clean stop."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from glider_cosim.master import Disturbance
from glider_cosim.runner import simulate
from glider_cosim.scenarios.scenario import Scenario

pytestmark = pytest.mark.integration


@settings(
    max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    K_L=st.floats(250.0, 350.0),
    K_Fdelta=st.floats(15.0, 45.0),
    V_0=st.floats(0.1, 0.35),
    theta_g_0=st.floats(math.radians(-50), math.radians(-10)),
    K_c=st.floats(5.0, 40.0),
    noise=st.floats(0.0, 0.05),
    kick=st.floats(-0.3, 0.3),
)
def test_random_runs_are_finite_or_stop_cleanly(
    fmu_dir, K_L, K_Fdelta, V_0, theta_g_0, K_c, noise, kick
):
    consts = {"K_L": K_L, "K_Fdelta": K_Fdelta}
    sc = Scenario(
        name="property",
        stop_time=10.0,
        parameters={
            "plant": {**consts, "V_0": V_0, "theta_g_0": theta_g_0, "noise_std": noise},
            "observer": dict(consts),
            "controller": {**consts, "K_c": K_c},
        },
        disturbances=[Disturbance("plant.F_z", "pulse", 3.0, kick, 1.0)],
    )
    r = simulate(sc, None, fmu_dir=fmu_dir, build=False)
    assert r.status in ("ok", "stopped")
    if r.status == "stopped":
        assert "glider stalled" in r.message and "fmi2DoStep at t = " in r.message
    assert np.all(np.isfinite(r.data))
    assert len(r.data) >= 1
