"""Sec. 5.2 / Fig. 8 scenarios: held tail, observer initialised 2 s after release."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glider_cosim.runner import simulate
from glider_cosim.scenarios.scenario import load_scenario

pytestmark = pytest.mark.integration


def _run(fmu_dir, tail: int, k_udelta: float | None = None):
    sc = load_scenario(f"sec52-tail{tail}")
    if k_udelta is not None:
        for inst in ("plant", "observer", "controller"):
            sc.parameters.setdefault(inst, {})["K_udelta"] = k_udelta
    return simulate(sc, None, fmu_dir=fmu_dir, build=False)


def test_observer_holds_its_estimate_until_it_is_initialised(fmu_dir):
    r = _run(fmu_dir, 30, 0.039)
    t, est = r.data[:, 0], r.column("observer.theta_hat")
    before = t <= 2.0 + 1e-9
    assert np.ptp(est[before]) == 0.0  # held at the default estimate
    assert np.ptp(r.column("plant.theta")[before]) > math.radians(5.0)  # the glider moves
    assert abs(est[t.searchsorted(2.5)] - est[0]) > math.radians(1.0)  # then it tracks
    after = t >= 5.0
    err = est[after] - r.column("plant.theta_meas")[after]
    assert r.status == "ok"
    assert np.sqrt(np.mean(err**2)) < math.radians(1.0)


def test_default_k_udelta_cannot_carry_the_held_tail(fmu_dir):
    r = _run(fmu_dir, 15)
    assert r.status == "stopped"
    assert "observer estimate glider stalled" in r.message
    assert 2.0 < r.data[-1, 0] < 6.0
