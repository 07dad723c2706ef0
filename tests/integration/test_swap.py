"""Swap test: our observer and controller close the loop around a plant that is not ours
(tests/integration/fmus_src/SwapTestPlant.py: Eqs. (1)-(9) written separately, adaptive
Dormand-Prince, no servo), and our plant runs under a controller that is not ours
(SwapTestController.py: a plain P law). Both settle at the paper's steady glide."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from glider_cosim.inputs.values import ValueCheckError
from glider_cosim.master import CoSimulation, Disturbance, System
from glider_cosim.runner import simulate
from glider_cosim.runner.recorders import ArrayRecorder
from glider_cosim.scenarios.scenario import parse_scenario
from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

pytestmark = pytest.mark.integration
SRC = Path(__file__).parent / "fmus_src"
THETA_GE = equilibrium(GliderParams()).theta_g
#: the foreign plant declares no units: its angles are plain numbers (rad)
SEC33_START = {"V_0": 0.2, "theta_g_0": math.radians(-35), "alpha_0": math.radians(1),
               "omega2_0": 0.0}  # fmt: skip
DISTURBANCES = ("plant.F_x", "plant.F_z", "plant.M_y")


@pytest.fixture(scope="module")
def foreign(tmp_path_factory) -> dict[str, Path]:
    """The two foreign FMUs (module names unique: one interpreter per process), packaged
    with our runtime: pythonfmu's own binary would abort the test process at exit."""
    from glider_cosim.fmus.python import build_slave_fmu

    out = tmp_path_factory.mktemp("swap_fmus")
    return {
        name: build_slave_fmu(SRC / f"{name}.py", out)
        for name in ("SwapTestPlant", "SwapTestController")
    }


def run_plant_alone(fmu: Path, stop: float, disturbances=()) -> np.ndarray:
    """theta_g of a plant FMU with the tail at 0 (and disturbances), every 20 ms."""
    system = System(
        fmus={"plant": fmu},
        connections=[],
        parameters={"plant": {"V_0": 0.2, "theta_g_0": math.radians(-35.0),
                              "alpha_0": math.radians(1.0)}},
        driven=dict.fromkeys(("plant.delta_cmd", *DISTURBANCES), 0.0),
        disturbances=list(disturbances),
        record=["plant.theta_g", "plant.V", "plant.z"],
    )  # fmt: skip
    sim = CoSimulation(system)
    rec = ArrayRecorder()
    try:
        sim.run(stop, rec)
    finally:
        sim.close()
    return rec.array()


def test_the_equilibrium_is_the_papers():
    assert math.degrees(THETA_GE) == pytest.approx(-22.577, abs=5e-4)


def test_foreign_plant_agrees_with_ours_in_open_loop(fmu_dir, foreign):
    # tail at zero (our servo stays at 0), then a 0.3 N downward force pulse and a
    # 0.01 N m moment step: both implementations of Eqs. (6)-(9) and of the disturbances
    pulses = [
        Disturbance("plant.F_z", "pulse", 5.0, 0.3, 1.0),
        Disturbance("plant.M_y", "step", 10.0, 0.01),
        Disturbance("plant.F_x", "pulse", 12.0, -0.2, 0.5),
    ]
    ours = run_plant_alone(fmu_dir / "GliderPlant.fmu", 20.0, pulses)
    theirs = run_plant_alone(foreign["SwapTestPlant"], 20.0, pulses)
    assert ours.shape == theirs.shape == (1001, 4)
    assert np.abs(ours[:, 1:] - theirs[:, 1:]).max() < 1e-6
    assert np.ptp(ours[250:, 1]) > 0.01  # the disturbances did move the glide angle


def test_our_observer_and_controller_around_a_foreign_plant(fmu_dir, foreign):
    sc = parse_scenario({
        "fmus": {"plant": str(foreign["SwapTestPlant"])},
        "plant": SEC33_START,
        "controller": {"law": "passivity", "K_c": 10.0},
    })  # fmt: skip
    r = simulate(sc, None, fmu_dir=fmu_dir, build=False)
    assert r.status == "ok", r.message
    th = r.column("plant.theta_g")
    assert len(th) == 3001
    assert th[0] == pytest.approx(math.radians(-35.0), abs=1e-12)
    assert abs(th[-1] - THETA_GE) < math.radians(0.2)
    assert r.metrics["settling_time_s"] is not None and r.metrics["settling_time_s"] < 30.0
    # the estimate follows the foreign plant's true state
    assert abs(r.column("observer.theta_g_hat")[-1] - th[-1]) < math.radians(0.2)


def test_a_unit_on_a_foreign_variable_without_one_is_refused(fmu_dir, foreign):
    """The foreign plant's theta_g_0 declares no unit: '-35 deg' is refused (issue 28)."""
    sc = parse_scenario({
        "fmus": {"plant": str(foreign["SwapTestPlant"])},
        "plant": {**SEC33_START, "theta_g_0": "-35 deg"},
    }, "s.toml")  # fmt: skip
    with pytest.raises(ValueCheckError, match=r"^s.toml: key 'plant.theta_g_0': '-35 deg' is "
                       r"invalid: theta_g_0 has no unit: expected a plain number$"):  # fmt: skip
        simulate(sc, None, fmu_dir=fmu_dir, build=False)


def test_our_plant_with_a_foreign_controller(fmu_dir, foreign):
    sc = parse_scenario({
        "fmus": {"controller": str(foreign["SwapTestController"])},
        "feedback": "state",
        "with_observer": False,
        "plant": SEC33_START,
        "controller": {"K_P": 0.5},
    })  # fmt: skip
    r = simulate(sc, None, fmu_dir=fmu_dir, build=False)
    assert r.status == "ok", r.message
    th = r.column("plant.theta_g")
    assert abs(th[-1] - THETA_GE) < math.radians(0.2)
    assert r.metrics["settling_time_s"] is not None and r.metrics["settling_time_s"] < 30.0
    assert np.max(np.abs(r.column("controller.delta_cmd"))) > math.radians(1.0)  # it acted
