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


@pytest.mark.parametrize(
    ("spec", "shown"),
    [
        ("0.1:0.5:5", ["0.1", "0.2", "0.3", "0.4", "0.5"]),
        ("2:30:15", [f"{k}.0" for k in range(2, 31, 2)]),
        ("0:0.1:6", ["0.0", "0.02", "0.04", "0.06", "0.08", "0.1"]),
        ("0:1:4", ["0.0", "0.333333333333333", "0.666666666666667", "1.0"]),
        ("1e-3:2e-3:3", ["0.001", "0.0015", "0.002"]),
        ("0.3,0.7", ["0.3", "0.7"]),
        ("7:7:1", ["7.0"]),
    ],
)
def test_swept_values_are_written_as_the_user_gave_them(spec, shown, tmp_path):
    """A range's values are its exact decimals (15 significant digits at most), and the
    number passed on is float() of the text sweep.csv shows (linspace gave
    0.30000000000000004 for 0.1:0.5:5)."""
    import csv

    from glider_cosim.sweeps.store import SweepStore

    values = parse_param(f"controller.K_c={spec}").values
    assert [repr(v) for v in values] == shown
    assert all(float(t) == v for t, v in zip(shown, values, strict=True))
    with SweepStore(tmp_path / "sweep.csv", ["run_id", "controller.K_c", "status"]) as store:
        for i, v in enumerate(values):
            store.add({"run_id": f"r{i}", "controller.K_c": v, "status": "ok"})
    with open(tmp_path / "sweep.csv", newline="") as f:
        assert [r["controller.K_c"] for r in csv.DictReader(f)] == shown


def test_a_range_in_degrees_steps_in_degrees():
    values = parse_param("plant.theta_g_0=-30 deg:-20 deg:3").values
    assert values == tuple(math.radians(d) for d in (-30.0, -25.0, -20.0))
    from glider_cosim.inputs.values import parse_quantity

    assert values[1] == parse_quantity("-25 deg")  # as --set "X deg" reads it
