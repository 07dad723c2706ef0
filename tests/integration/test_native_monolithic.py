"""The native floor (cosim/runner/monolithic.c): the native FMUs' C models in one C loop,
without FMI, give the native co-simulation's rows bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from glider_cosim.runner.monolithic import (
    COLUMNS,
    NativeMonolithic,
    seconds_per_step,
    simulate_monolithic,
    simulate_native_monolithic,
)
from glider_cosim.runner.run import simulate
from glider_cosim.scenarios.fields import ScenarioError
from glider_cosim.scenarios.scenario import load_scenario

pytestmark = pytest.mark.integration


SCENARIOS = ["default", "sec52-tail30", "fig5-6-observer-noise", "paper-pi-gains",
             "paper-p-gains"]  # fmt: skip


@pytest.mark.parametrize("name", SCENARIOS)
def test_the_c_loop_gives_the_native_cosimulations_rows_bit_for_bit(native_dir, name):
    sc = load_scenario(name)
    stop = min(sc.stop_time, 30.0)
    res = simulate(sc, None, fmu_dir=native_dir, build=False, plots=False, stop_time=stop)
    cosim = res.data[:, [res.columns.index(c) for c in COLUMNS]]
    floor, message = NativeMonolithic(sc, fmu_dir=native_dir).run(round(stop / sc.step))
    # the open loop and the P and PI gains stall the glider before 30 s: both loops stop
    # at the same point, with the plant's message
    assert (res.status, message is None) in (("ok", True), ("stopped", False))
    if message is not None:
        assert "glider stalled" in message and message.split(" at t = ")[0] in res.message
    assert floor.shape == cosim.shape and floor.shape[1] == len(COLUMNS)
    assert floor.tobytes() == cosim.tobytes()  # bit for bit, -0.0 and all
    if res.status == "ok":
        assert len(floor) == round(stop / sc.step) + 1
        assert np.array_equal(simulate_monolithic(sc, stop_time=stop, fmu_dir=native_dir), floor)
        assert np.array_equal(simulate_native_monolithic(sc, stop_time=stop, fmu_dir=native_dir),
                              floor)  # fmt: skip


def test_a_stall_ends_the_rows_with_the_plants_message(native_dir):
    sc = load_scenario("default")
    sc.parameters.setdefault("plant", {})["V_0"] = 1e-6  # below the stall speed at once
    loop = NativeMonolithic(sc, fmu_dir=native_dir)
    rows, message = loop.run(100)
    assert len(rows) == 1 and "glider stalled: V = " in message


DISTURBANCE = """
[[disturbance]]
target = "plant.F_z"
kind = "pulse"
time = 5.0
duration = 1.0
value = 0.2
"""
EVENT = """
[[event]]
when = "time >= 5"
set = { "controller.K_c" = 3 }
"""


@pytest.mark.parametrize(
    "text, message",
    [(DISTURBANCE, "the native monolithic loop has no disturbances"),
     ('feedback = "state"\nwith_observer = false\n', "the native monolithic loop runs the "
      "observer: with_observer = false is not supported"),
     (EVENT, "the native monolithic loop supports no events, FMU swaps or inputs")],
)  # fmt: skip
def test_what_the_loop_cannot_run_is_named(native_dir, tmp_path, text, message):
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as err:
        NativeMonolithic(load_scenario(path), fmu_dir=native_dir)
    assert str(err.value) == f"{path}: {message}"


def test_the_floor_is_timed_per_step(native_dir):
    assert seconds_per_step(load_scenario("default"), native_dir, repeat=2) > 0
