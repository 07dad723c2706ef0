"""Swap test: our observer and controller around a plant that is not ours, and our plant
driven by a controller that is not ours; both stabilise."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from glider_cosim.runner import simulate
from glider_cosim.scenario import parse_scenario
from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

pytestmark = pytest.mark.integration
SRC = Path(__file__).parent / "fmus_src"
THETA_GE = equilibrium(GliderParams()).theta_g


@pytest.fixture(scope="module")
def foreign(tmp_path_factory):
    from pythonfmu.builder import FmuBuilder

    out = tmp_path_factory.mktemp("swap")
    return {n: Path(FmuBuilder.build_FMU(SRC / f"{n}.py", dest=out))
            for n in ("SwapTestPlant", "SwapTestController")}  # fmt: skip


def test_our_observer_and_controller_around_another_plant(fmu_dir, foreign):
    sc = parse_scenario({"fmus": {"plant": str(foreign["SwapTestPlant"])},
                         "controller": {"K_c": 10.0}})  # fmt: skip
    r = simulate(sc, None, fmu_dir=fmu_dir, build=False)
    assert r.status == "ok", r.message
    th = r.column("plant.theta_g")
    assert abs(th[0] - math.radians(-35.0)) < 1e-12
    assert abs(th[-1] - THETA_GE) < math.radians(0.2)
    assert r.metrics["settling_time_s"] is not None


def test_our_plant_with_another_controller(fmu_dir, foreign):
    sc = parse_scenario({"fmus": {"controller": str(foreign["SwapTestController"])},
                         "record": ["plant.theta_g", "controller.delta_cmd"]})  # fmt: skip
    r = simulate(sc, None, fmu_dir=fmu_dir, build=False)
    assert r.status == "ok", r.message
    th = r.column("plant.theta_g")
    assert abs(th[-1] - THETA_GE) < math.radians(0.2)
    assert max(abs(r.column("controller.delta_cmd"))) > 0.01  # it did act
