"""Robustness: every parameter validated, illegal call sequences, non-finite inputs,
repeated use, interruption."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

from glider_cosim.fmus.python import COMPONENTS
from glider_cosim.master import CoSimulation, FMUCallError, System
from glider_cosim.master.instance import _extracted
from glider_cosim.runner import simulate
from glider_cosim.runner.recorders import ArrayRecorder
from glider_cosim.scenarios.scenario import load_scenario

pytestmark = pytest.mark.integration
NAMES = [c.name for c in COMPONENTS]


def parameters(fmu: Path):
    md = read_model_description(str(fmu))
    return [v for v in md.modelVariables if v.causality == "parameter"]


def one_instance(fmu: Path, params: dict) -> CoSimulation:
    md = read_model_description(str(fmu))
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    starts = {f"x.{v.name}": float(v.start) for v in md.modelVariables if v.name in inputs}
    return CoSimulation(
        System(fmus={"x": fmu}, connections=[], parameters={"x": params}, driven=starts)
    )


@pytest.mark.parametrize("name", NAMES)
def test_every_parameter_is_validated(flavor_dir, name):
    """NaN for every Real parameter, an out-of-range value for every Integer one."""
    fmu = flavor_dir / f"{name}.fmu"
    checked = 0
    for v in parameters(fmu):
        if v.type == "Boolean":
            continue  # every Boolean value is valid
        bad = float("nan") if v.type == "Real" else -1
        sim = one_instance(fmu, {v.name: bad})
        with pytest.raises(FMUCallError) as err:
            sim.run(0.1, ArrayRecorder())
        sim.close()
        assert err.value.call == "fmi2ExitInitializationMode", v.name
        assert f"{v.name} = {'nan' if v.type == 'Real' else bad} is invalid: expected" in str(
            err.value
        ), str(err.value)
        checked += 1
    assert checked >= 8


def test_consistency_checks(flavor_dir):
    cases = [
        ("GliderObserver", {"f_sample": 50.0, "f_cutoff": 25.0}, "below the Nyquist frequency"),
        ("GliderPlant", {"delta_max": 0.1, "delta_0": 0.2}, "delta_0 = 0.2 is invalid"),
        ("GliderPlant", {"K_M0": -0.39}, r"K_L0 \+ K_L\*alpha_e = -8.05\d* is invalid"),
    ]
    for name, params, message in cases:
        sim = one_instance(flavor_dir / f"{name}.fmu", params)
        with pytest.raises(FMUCallError, match=message) as err:
            sim.run(0.1, ArrayRecorder())
        sim.close()
        # our message alone: no exception type, no traceback
        assert "returned fmi2Error: [fmi2Error] " in str(err.value)
        assert "Error: " not in str(err.value).partition("[fmi2Error] ")[2]


def test_non_finite_input_is_refused_at_the_step(flavor_dir):
    fmu = flavor_dir / "GliderPlant.fmu"
    sim = one_instance(fmu, {})
    sim.system.driven["x.F_x"] = float("inf")
    with pytest.raises(FMUCallError) as err:
        sim.run(0.1, ArrayRecorder())
    sim.close()
    assert err.value.call == "fmi2DoStep"
    assert "input F_x = inf at t = 0 s is invalid: expected a finite value" in str(err.value)


def raw_slave(fmu: Path) -> FMU2Slave:
    md = read_model_description(str(fmu))
    s = FMU2Slave(
        guid=md.guid,
        unzipDirectory=_extracted(fmu),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="seq",
    )
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.md = md
    return s


def vr(s: FMU2Slave, name: str) -> int:
    return next(v.valueReference for v in s.md.modelVariables if v.name == name)


@pytest.mark.parametrize(
    "sequence",
    ["step_before_init", "wrong_time", "zero_step", "negative_step", "fixed_after_init",
     "set_output", "tunable_out_of_range"],
)  # fmt: skip
def test_illegal_call_sequences_give_an_error_not_a_crash(flavor_dir, sequence):
    s = raw_slave(flavor_dir / "GliderController.fmu")
    if sequence != "step_before_init":
        s.enterInitializationMode()
        s.exitInitializationMode()
    with pytest.raises(FMICallException) as err:
        if sequence == "step_before_init":
            s.doStep(0.0, 0.02)
        elif sequence == "wrong_time":
            s.doStep(0.0, 0.02)
            s.doStep(0.5, 0.02)
        elif sequence == "zero_step":
            s.doStep(0.0, 0.0)
        elif sequence == "negative_step":
            s.doStep(0.0, -0.02)
        elif sequence == "fixed_after_init":
            s.setReal([vr(s, "delta_max")], [0.5])
        elif sequence == "set_output":
            s.setReal([vr(s, "delta_cmd")], [0.5])
        else:
            s.setReal([vr(s, "K_c")], [-3.0])
    assert err.value.status == 3  # fmi2Error, never fmi2Fatal
    # only getters, reset and free are accepted now
    with pytest.raises(FMICallException) as again:
        s.doStep(0.0, 0.02)
    assert again.value.status == 3
    s.getReal([vr(s, "delta_cmd")])
    s.reset()
    s.freeInstance()


def test_illegal_sequence_messages_through_the_master(flavor_dir):
    sim = one_instance(flavor_dir / "GliderController.fmu", {})
    sim.initialize()
    inst = sim.instances["x"]
    with pytest.raises(FMUCallError, match=r"delta_max is a fixed parameter: it cannot be set"):
        sim._set_value(inst, "delta_max", 0.3)
    assert inst.failed and not inst.fatal
    sim.reset()  # fmi2Reset works after an error
    assert not inst.failed
    sim.close()
    sim = one_instance(flavor_dir / "GliderController.fmu", {})
    sim.initialize()
    sim._set_value(sim.instances["x"], "K_c", 4.0)  # tunable: fine
    with pytest.raises(FMUCallError, match=r"K_c = -1.0 is invalid: expected a finite value"):
        sim._set_value(sim.instances["x"], "K_c", -1.0)
    sim.close()


def test_repeated_use_in_one_process(fmu_dir):
    """Many instantiate/initialise/step/reset/free cycles; several masters at once."""
    sc = load_scenario(None)
    from glider_cosim.scenarios.system import system_for

    a = CoSimulation(system_for(sc, fmu_dir))
    b = CoSimulation(system_for(sc, fmu_dir))  # a second host in the same process
    a.initialize()
    b.initialize()
    for k in range(20):
        for sim in (a, b):
            sim.reset({"controller": {"K_c": 8.0 + k % 3}})
            for _ in range(10):
                sim.communication_point()
                sim.do_step()
    a.close()
    b.close()
    for _ in range(20):  # fresh instances each time, binaries shared
        r = simulate(sc, None, fmu_dir=fmu_dir, build=False, stop_time=0.2)
        assert r.status == "ok"
    # another host in the same process: fmpy's own simulate_fmu on the plant
    from fmpy import simulate_fmu

    res = simulate_fmu(str(fmu_dir / "GliderPlant.fmu"), stop_time=1.0, output_interval=0.02,
                       output=["theta_g"])  # fmt: skip
    assert len(res) == 51 and np.isfinite(res["theta_g"]).all()


def test_ctrl_c_keeps_what_was_computed(fmu_dir, tmp_path):
    code = "from glider_cosim.cli import console_main; console_main()"
    p = subprocess.Popen(
        [sys.executable, "-c", code, "run", "--stop-time", "3600", "--out", str(tmp_path),
         "--fmu-dir", str(fmu_dir), "--no-plots"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    results = tmp_path / "results.csv"
    deadline = time.time() + 60
    while time.time() < deadline and (not results.exists() or results.stat().st_size < 200_000):
        time.sleep(0.2)
    os.kill(p.pid, signal.SIGINT)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert "interrupted; results so far are written" in err
    rows = results.read_text().splitlines()
    assert len(rows) > 500
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["status"] == "interrupted" and m["rows"] == len(rows) - 1
