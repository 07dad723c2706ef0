"""Units that mean what they say (issue 28, point 2): a value may carry its variable's
declared unit, or ``deg`` for a ``rad`` variable; any other unit, and every unit on a
variable without one, is refused naming the expected unit. One rule for ``--set``,
scenario files and sweep specs."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import pytest

from glider_cosim.inputs.check import check_ranges
from glider_cosim.inputs.values import (
    Degrees,
    Quantity,
    ValueCheckError,
    check_value,
    parse_quantity,
)
from glider_cosim.scenarios.overrides import parse_sets
from glider_cosim.scenarios.scenario import load_scenario, parse_scenario
from glider_cosim.sweeps.spec import SweepSpecError, check_ranges_of, parse_param
from glider_cosim.sweeps.store import describe_failures


@pytest.mark.parametrize(
    ("text", "value", "unit"),
    [
        ("0.2 m/s", 0.2, "m/s"),
        ("10 Hz", 10.0, "Hz"),
        ("10Hz", 10.0, "Hz"),
        ("-30 deg", math.radians(-30), "deg"),
        ("1e-3 kg.m2", 1e-3, "kg.m2"),
        ("6 1", 6.0, "1"),
    ],
)
def test_parse_quantity(text, value, unit):
    q = parse_quantity(text)
    assert isinstance(q, Quantity) and q.unit == unit and q.text == text
    assert float(q) == pytest.approx(value)
    assert isinstance(q, Degrees) == (unit == "deg")


@pytest.mark.parametrize("text", ["6", "fast", "m/s", "1e999 m", "6 deg deg", ""])
def test_parse_quantity_refuses_what_is_no_quantity(text):
    assert parse_quantity(text) is None


def _sets(item: str) -> None:
    """``--set ITEM`` checked as ``run`` checks it before building anything."""
    overrides = parse_sets([item])
    params: dict = {}
    for key, value in overrides.items():
        inst, _, name = key.partition(".")
        params.setdefault(inst, {})[name] = value
    check_ranges(params, lambda ref: f"--set {item!r}")


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ("controller.K_c=6 deg",
         "--set 'controller.K_c=6 deg': '6 deg' is invalid: K_c has no unit: expected a plain "
         "number"),
        ("controller.K_c=6 Hz",
         "--set 'controller.K_c=6 Hz': '6 Hz' is invalid: K_c has no unit: expected a plain "
         "number"),
        ("plant.V_0=0.2 km/s",
         "--set 'plant.V_0=0.2 km/s': '0.2 km/s' is invalid: V_0 is in m/s: expected a number "
         "in m/s"),
        ("plant.V_0=3 deg",
         "--set 'plant.V_0=3 deg': '3 deg' is invalid: V_0 is in m/s: expected a number in m/s"),
        ("plant.theta_g_0=-30 m",
         "--set 'plant.theta_g_0=-30 m': '-30 m' is invalid: theta_g_0 is in rad: expected a "
         "number in rad or 'X deg'"),
        ("plant.noise_seed=3 s",
         "--set 'plant.noise_seed=3 s': '3 s' is invalid: noise_seed has no unit: expected a "
         "plain number"),
    ],
)  # fmt: skip
def test_set_refuses_other_units(item, message):
    with pytest.raises(ValueCheckError) as err:
        _sets(item)
    assert str(err.value) == message


@pytest.mark.parametrize(
    ("item", "value"),
    [
        ("plant.V_0=0.2 m/s", 0.2),
        ("observer.f_cutoff=10 Hz", 10.0),
        ("controller.K_I=3 Hz", 3.0),
        ("plant.theta_g_0=-30 deg", math.radians(-30)),
        ("plant.theta_g_0=-0.5 rad", -0.5),
        ("controller.t_enable=2 s", 2.0),
    ],
)
def test_set_takes_the_declared_unit(item, value):
    _sets(item)
    assert float(next(iter(parse_sets([item]).values()))) == pytest.approx(value)


def test_scenario_files_follow_the_same_rule():
    sc = parse_scenario({"plant": {"V_0": "0.2 m/s"}, "observer": {"f_cutoff": "10 Hz"}}, "s.toml")
    check_ranges(sc.parameters, lambda ref: f"s.toml: key '{ref}'")
    assert sc.parameters["plant"]["V_0"] == 0.2
    sc = parse_scenario({"controller": {"K_c": "6 deg"}}, "s.toml")
    with pytest.raises(ValueCheckError, match=r"^s.toml: key 'controller.K_c': '6 deg' is "
                       r"invalid: K_c has no unit: expected a plain number$"):  # fmt: skip
        check_ranges(sc.parameters, lambda ref: f"s.toml: key '{ref}'")


def _var(name: str, unit: str | None, type_: str = "Real") -> SimpleNamespace:
    return SimpleNamespace(name=name, unit=unit, declaredType=None, type=type_, min=None,
                           max=None)  # fmt: skip


def test_the_model_description_check_takes_the_declared_unit_only():
    """A foreign FMU's variables: the unit its model description declares."""
    md = SimpleNamespace(unitDefinitions=[])
    assert check_value(parse_quantity("2 N"), md, _var("F", "N"), "w") == 2.0
    assert check_value(parse_quantity("90 deg"), md, _var("a", "rad"), "w") == pytest.approx(
        math.pi / 2
    )
    for text, var, expected in [
        ("6 deg", _var("K", None), "K has no unit: expected a plain number"),
        ("2 kN", _var("F", "N"), "F is in N: expected a number in N"),
        ("2 deg", _var("F", "N"), "F is in N: expected a number in N"),
    ]:
        with pytest.raises(ValueCheckError) as err:
            check_value(parse_quantity(text), md, var, "w")
        assert str(err.value) == f"w: {text!r} is invalid: {expected}"


# ------------------------------------------------------------------ sweep specs
@pytest.mark.parametrize(
    ("item", "message"),
    [
        ("controller.K_c=-1,5",
         "--param 'controller.K_c=-1,5': -1 is invalid: expected a finite value in (0, inf)"),
        ("controller.K_c=6 deg,8",
         "--param 'controller.K_c=6 deg,8': '6 deg' is invalid: K_c has no unit: expected a "
         "plain number"),
        ("plant.V_0=0.2 km/s:0.4 km/s:3",
         "--param 'plant.V_0=0.2 km/s:0.4 km/s:3': '0.2 km/s' is invalid: V_0 is in m/s: "
         "expected a number in m/s"),
        ("plant.V_0=uniform(-1,2)",
         "--param 'plant.V_0=uniform(-1,2)': -1.0 is invalid: expected a finite value in "
         "(0, inf) (m/s)"),
    ],
)  # fmt: skip
def test_sweep_values_are_checked_like_set(item, message):
    with pytest.raises(SweepSpecError) as err:
        check_ranges_of([parse_param(item)], load_scenario(None))
    assert str(err.value) == message


def test_sweep_values_take_the_declared_unit():
    spec = parse_param("plant.V_0=0.2 m/s,0.3 m/s")
    check_ranges_of([spec], load_scenario(None))
    assert spec.values == (0.2, 0.3) and all(type(v) is float for v in spec.values)
    spec = parse_param("plant.theta_g_0=-30 deg:-20 deg:3")
    check_ranges_of([spec], load_scenario(None))
    assert spec.values == pytest.approx(tuple(math.radians(d) for d in (-30, -25, -20)))


def test_failed_runs_are_named():
    rows = [
        {"run_id": "a", "seed": "", "controller.K_c": "0.1", "status": "stopped",
         "message": "observer: fmi2DoStep at t = 3.9 s returned fmi2Discard: stalled"},
        {"run_id": "b", "seed": "2", "controller.K_c": "0.05", "status": "error",
         "message": "x" * 300},
    ]  # fmt: skip
    assert describe_failures(rows, 4, Path("out/sweep.csv"), ["controller.K_c"]) == [
        "  failed: controller.K_c=0.1: stopped: observer: fmi2DoStep at t = 3.9 s returned "
        "fmi2Discard: stalled",
        f"  failed: controller.K_c=0.05, seed 2: error: {'x' * 197}...",
        f"  and 2 more failed (each with its status and message in {Path('out/sweep.csv')})",
    ]
    assert describe_failures([], 0, Path("s.csv"), []) == []
