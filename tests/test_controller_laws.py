"""Pure-model tests of the control laws."""

from __future__ import annotations

import math

import pytest

from glider_controller.laws import PIController, passivity_law, passivity_output
from glider_plant.model import derivatives, equilibrium, plant_step
from glider_plant.params import GliderParams

P = GliderParams()
E = equilibrium(P)


def test_passivity_output_vanishes_at_equilibrium():
    assert passivity_output(E.V, E.theta_g, P, E) == pytest.approx(0.0, abs=1e-15)
    assert passivity_law(E.V, E.theta_g, 2.0, P, E, 1.5) == pytest.approx(0.0, abs=1e-15)


def test_passivity_sign_pushes_the_glide_angle_back():
    steep = E.theta_g - math.radians(12.5)  # gliding too steeply
    u = passivity_law(E.V, steep, 10.0, P, E, 1.5)
    assert u > 0.0
    x = (E.V, steep, E.alpha, 0.0)
    # with the law, theta_g turns towards the equilibrium faster than without it
    x1 = x + (0.0, 0.0)
    x0 = x + (0.0, 0.0)
    for _ in range(50):
        u = passivity_law(x1[0], x1[1], 10.0, P, E, 1.5)
        x1, _ = plant_step(x1, u, u, 0.02, P, 0.01)
        x0, _ = plant_step(x0, 0.0, 0.0, 0.02, P, 0.01)
    assert abs(x1[1] - E.theta_g) < abs(x0[1] - E.theta_g)
    # the opposite sign makes it worse
    assert derivatives(0, x, +0.1, P)[1] > derivatives(0, x, -0.1, P)[1]


def test_passivity_law_is_bounded_by_pi_over_2_kc_and_saturates():
    far = passivity_law(E.V, E.theta_g - 1.0, 1.0, P, E, 10.0)
    assert 0 < far < math.pi / 2
    assert passivity_law(E.V, E.theta_g - 1.0, 1.0, P, E, 0.2) == 0.2


def test_p_law_opposes_the_error():
    c = PIController(K_P=2.0, K_I=0.0, delta_max=1.0)
    assert c.output(-0.1) == pytest.approx(0.2)
    assert c.output(0.1) == pytest.approx(-0.2)
    assert c.output(-1.0) == 1.0  # saturated


def test_pi_anti_windup_holds_the_integrator_in_saturation():
    c = PIController(K_P=2.0, K_I=1.0, delta_max=0.3)
    for _ in range(100):  # 2 s at a large error: saturated throughout
        c.update(-0.5, 0.02)
    assert c.output(-0.5) == 0.3
    assert c.integral == 0.0  # held: winding up was prevented
    naive = -0.5 * 2.0  # what a plain integrator would have accumulated
    # once the error reverses, the output leaves saturation at once
    assert c.output(0.05) == pytest.approx(-0.1)
    assert naive < 0
    d = PIController(K_P=0.1, K_I=1.0, delta_max=0.3)
    for _ in range(10):
        d.update(-0.5, 0.02)
    assert d.integral == pytest.approx(-0.1)  # unsaturated: integrates
