"""The held-tail steady glide, its stability limit and the release runs (pure model)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glider_cosim.runner.heldtail import (
    HeldTailError,
    carried,
    held_glide,
    largest_carried_u,
    release_run,
)
from glider_cosim.runner.metrics import reference_glide_angle
from glider_plant.model import derivatives, equilibrium
from glider_plant.params import GliderParams

P = GliderParams()


@pytest.mark.parametrize("u_deg", [0.0, 2.0, 15.0, 45.0])
def test_held_glide_is_a_steady_state_of_the_model(u_deg):
    u = math.radians(u_deg)
    g = held_glide(P, u)
    f = derivatives(0.0, (g.V, g.theta_g, g.alpha, 0.0), u, P)
    assert np.max(np.abs(f)) < 1e-12
    assert g.V > 0


def test_zero_hold_is_the_open_loop_equilibrium():
    g, e = held_glide(P, 0.0), equilibrium(P)
    assert (g.V, g.theta_g, g.alpha) == pytest.approx((e.V, e.theta_g, e.alpha), abs=1e-12)
    assert g.max_real == pytest.approx(-0.0916, abs=1e-4)  # the open loop's slow pair


def test_stability_limit_is_a_limit_in_u_so_delta_max_scales_with_1_over_k_udelta():
    u1 = largest_carried_u(P)
    assert held_glide(P, u1 - 1e-6).stable and not held_glide(P, u1 + 1e-5).stable
    for k in (0.5, 0.1):
        assert largest_carried_u(GliderParams(K_udelta=k)) == pytest.approx(u1, abs=1e-7)


def test_release_runs_below_and_above_the_limit():
    u1 = largest_carried_u(P)
    assert carried(release_run(P, 0.5 * u1, stop_time=60.0))
    far = release_run(P, 4.0 * u1, stop_time=60.0)
    assert not carried(far)
    status, end, _ = release_run(P, math.radians(60.0), stop_time=60.0)
    assert status == "stall" and end == pytest.approx(11.1, abs=0.05)  # as sec53-literal


def test_bad_hold_is_refused():
    with pytest.raises(HeldTailError, match="expected a finite angle"):
        held_glide(P, math.nan)


def test_metrics_reference_is_the_held_tail_glide_for_an_open_loop_law():
    d = math.radians(1.0)
    assert reference_glide_angle(P, {"law": 0, "delta_open": d}) == pytest.approx(
        held_glide(P, d).theta_g
    )
    assert reference_glide_angle(P, {"law": 1, "delta_open": d}) == equilibrium(P).theta_g
