"""Our FMI 2.0 binding (``glider_cosim.master.binding``, issue 48) against fmpy's
``FMU2Slave`` on the project's FMUs: the master's run on either is the same to the bit;
a failing call raises our typed error naming the call and the status; the FMU state and
the directional derivatives come back as fmpy gets them; a binary that is not an FMU's
is refused naming what it lacks."""

from __future__ import annotations

import shutil

import pytest
from fmpy import calloc, free
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

from glider_cosim.inputs.archives import FMI2_PLATFORM, LIBRARY_SUFFIX, read_fmu
from glider_cosim.master import CoSimulation, binding
from glider_cosim.master.binding import FMU2Binary
from glider_cosim.master.errors import FMIStatusError
from glider_cosim.master.instance import _extracted
from glider_cosim.runner.recorders import ArrayRecorder
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for

pytestmark = pytest.mark.integration


def fmpy_callbacks(logger):
    """The callbacks the master made with fmpy before issue 48."""
    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(logger)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    return cb


def default_run(folder, stop: float = 20.0):
    """The default scenario's rows to ``stop`` s and the kinds of the instances' slaves."""
    sc = load_scenario(None)
    sim = CoSimulation(system_for(sc, folder), step=sc.step, coupling=sc.coupling)
    rec = ArrayRecorder()
    try:
        sim.run(stop, rec)
    finally:
        sim.close()
    return rec.array(), {type(i.slave) for i in sim.instances.values()}


def test_the_run_on_the_binding_is_the_run_on_fmpy_to_the_bit(flavor_dir, monkeypatch):
    ours, kinds = default_run(flavor_dir)
    assert kinds == {FMU2Binary}
    monkeypatch.setattr(binding, "FMU2Binary", FMU2Slave)
    monkeypatch.setattr(binding, "callbacks", fmpy_callbacks)
    theirs, kinds = default_run(flavor_dir)
    assert kinds == {FMU2Slave}
    assert ours.shape == theirs.shape == (1001, ours.shape[1]) and ours.shape[1] > 5
    assert ours.tobytes() == theirs.tobytes()


def opened(fmu, cls=FMU2Binary, name: str = "probe"):
    md = read_fmu(fmu, None, schema=False)
    slave = cls(guid=md.guid, unzipDirectory=_extracted(fmu),
                modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)  # fmt: skip
    vr = {v.name: v.valueReference for v in md.modelVariables}
    return slave, vr


def started(fmu, log: list, cls=FMU2Binary, cb=binding.callbacks, params=None):
    slave, vr = opened(fmu, cls)
    callbacks = cb(lambda env, name, status, cat, msg: log.append((status, msg)))
    slave.instantiate(callbacks=callbacks, loggingOn=True)
    slave.setupExperiment(None, 0.0)
    for name, value in (params or {}).items():
        slave.setReal([vr[name]], [value])
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    return slave, vr, callbacks


def test_a_failing_call_raises_our_error_naming_the_call_and_the_status(native_dir):
    log: list = []
    slave, vr = opened(native_dir / "GliderController.fmu")
    cb = binding.callbacks(lambda env, name, status, cat, msg: log.append((status, msg)))
    slave.instantiate(callbacks=cb, loggingOn=True)
    slave.setupExperiment(None, 0.0)
    slave.setInteger([vr["law"]], [7])  # no such law: refused at initialisation
    with pytest.raises(FMIStatusError) as err:
        slave.enterInitializationMode()
        slave.exitInitializationMode()
    e = err.value
    assert isinstance(e, RuntimeError) and e.status == 3 and e.function == e.call
    assert e.call in ("fmi2EnterInitializationMode", "fmi2ExitInitializationMode")
    assert str(e) == f"{e.call} returned fmi2Error"
    assert any(status == 3 and b"law" in msg for status, msg in log), log
    slave.fmi2FreeInstance(slave.component)


def test_the_fmu_state_and_the_directional_derivatives_are_fmpys(native_dir):
    plant = native_dir / "GliderPlant.fmu"
    outs = ["theta", "V", "alpha", "omega2", "delta"]
    got = {}
    for cls, cb in ((FMU2Binary, binding.callbacks), (FMU2Slave, fmpy_callbacks)):
        log: list = []
        slave, vr, keep = started(plant, log, cls, cb, {"delta_0": 0.05})
        slave.setReal([vr["delta_cmd"]], [0.1])
        for k in range(10):
            slave.doStep(k * 0.02, 0.02)
        state = slave.getFMUstate()
        later = []
        for k in range(10, 15):
            slave.doStep(k * 0.02, 0.02)
            later.append(slave.getReal([vr[n] for n in outs]))
        slave.setFMUstate(state)
        again = []
        for k in range(10, 15):
            slave.doStep(k * 0.02, 0.02)
            again.append(slave.getReal([vr[n] for n in outs]))
        assert again == later and later[0] != later[-1]
        slave.freeFMUstate(state)
        derivative = slave.getDirectionalDerivative([vr["der(V)"], vr["der(theta_g)"]],
                                                    [vr["delta_cmd"]], [1.0])  # fmt: skip
        got[cls] = (later, derivative, slave.getInteger([vr["noise_seed"]]))
        slave.terminate()
        slave.fmi2FreeInstance(slave.component)
    assert got[FMU2Binary] == got[FMU2Slave]
    assert all(isinstance(x, float) for x in got[FMU2Binary][1])


def test_a_binary_without_the_fmi_functions_is_refused_naming_one(tmp_path):
    folder = tmp_path / "binaries" / FMI2_PLATFORM
    folder.mkdir(parents=True)
    with pytest.raises(FileNotFoundError, match="no shared library"):
        FMU2Binary(guid="{}", unzipDirectory=str(tmp_path), modelIdentifier="Nope",
                   instanceName="x")  # fmt: skip
    # a shared library of another kind: one of Python's own extension modules
    import _ctypes

    other = getattr(_ctypes, "__file__", None)
    if other is None or not other.endswith(LIBRARY_SUFFIX):
        pytest.skip("_ctypes is built in: no shared library to try")
    shutil.copy(other, folder / f"NotAnFMU{LIBRARY_SUFFIX}")
    with pytest.raises(OSError, match=f"NotAnFMU{LIBRARY_SUFFIX} has no function fmi2Instantiate"):
        FMU2Binary(guid="{}", unzipDirectory=str(tmp_path), modelIdentifier="NotAnFMU",
                   instanceName="x")  # fmt: skip
