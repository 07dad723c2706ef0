"""The sweep's --param grammar and run expansion (no Dask)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.sweeps.sweep import SweepSpecError, parse_param, run_id


def test_lists_ranges_and_degrees():
    assert parse_param("controller.K_c=6,8,10,15").values == (6.0, 8.0, 10.0, 15.0)
    assert parse_param("controller.K_c=2:20:10").values == pytest.approx(
        tuple(np.linspace(2, 20, 10))
    )
    assert parse_param("plant.theta_g_0=-30 deg,-40 deg").values == pytest.approx(
        (math.radians(-30), math.radians(-40))
    )


def test_random_specs_draw_around_the_nominal():
    rng = np.random.default_rng(1)
    u = parse_param("plant.K_L=uniform(-20%,+20%)")
    draws = [u.draw(300.0, rng) for _ in range(2000)]
    assert 240.0 <= min(draws) and max(draws) <= 360.0
    assert np.mean(draws) == pytest.approx(300.0, rel=0.02)
    n = parse_param("plant.K_D=normal(10%)")
    draws = [n.draw(200.0, rng) for _ in range(4000)]
    assert np.std(draws) == pytest.approx(20.0, rel=0.08)
    a = parse_param("plant.noise_std=uniform(0,0.05)")
    assert all(0 <= a.draw(1.0, rng) <= 0.05 for _ in range(100))


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ("K_c=1,2", r"expected INSTANCE.NAME=SPEC"),
        ("robot.K_c=1", r"expected INSTANCE.NAME=SPEC"),
        ("controller.K_c=a,b", r"'a' is not a number"),
        ("controller.K_c=1:2", r"a range is START:STOP:NUM"),
        ("controller.K_c=1:2:x", r"NUM 'x' must be a whole number"),
        ("plant.K_L=uniform(20%)", r"uniform takes 2 argument"),
        ("plant.K_L=normal(-5%)", r"standard deviation must be >= 0"),
        ("plant.K_L=normal(abc)", r"'abc' is not a number or a percentage"),
    ],
)
def test_bad_specs_are_named(item, message):
    with pytest.raises(SweepSpecError, match=message):
        parse_param(item)


def test_run_ids_are_deterministic():
    sc = load_scenario(None)
    a = run_id({"controller.K_c": 6.0}, 1, sc, 60.0)
    assert a == run_id({"controller.K_c": 6.0}, 1, sc, 60.0)
    assert a != run_id({"controller.K_c": 6.0}, 2, sc, 60.0)
    assert a != run_id({"controller.K_c": 8.0}, 1, sc, 60.0)
