"""fmpy is the master's FMI layer (issue 53): every FMU is read by
``fmpy.read_model_description`` and runs on fmpy's ``FMU2Slave``/``FMU3Slave``; the C
fast loop steps the very instances fmpy created and gives the bits of the fmpy path."""

from __future__ import annotations

import ctypes
import zipfile

import pytest
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.model_description import ModelDescription

from glider_cosim.inputs.archives import InputFileError, read_fmu
from glider_cosim.master import CoSimulation
from glider_cosim.master.errors import SystemSpecError
from glider_cosim.master.instance import Instance, in_cache
from glider_cosim.runner import simulate
from glider_cosim.runner.recorders import ArrayRecorder
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module", params=["python-2", "native-2", "python-3", "native-3"])
def fmus(request, fmu_dir, native_dir, fmi3_dirs):
    flavor, fmi = request.param.split("-")
    if fmi == "3":
        return fmi3_dirs[flavor]
    return fmu_dir if flavor == "python" else native_dir


def _address(fn) -> int:
    return ctypes.cast(fn, ctypes.c_void_p).value


def test_the_instances_are_fmpys_and_the_c_loop_calls_them(fmus):
    sim = CoSimulation(system_for(load_scenario("default"), fmus))
    try:
        sim.run(1.0, ArrayRecorder())
        assert sim._fast is not None
        fns, comps = list(sim._fast._fns), list(sim._fast._comps)
        for i, inst in enumerate(sim.instances.values()):
            assert isinstance(inst.md, ModelDescription)
            if inst.fmi == 2:
                assert isinstance(inst.slave, FMU2Slave)
                # the C loop steps the instance fmpy made, through the library fmpy loaded
                assert comps[i] == inst.slave.component
                assert fns[i] == _address(inst.slave.dll.fmi2DoStep)
            else:
                assert isinstance(inst.slave.slave, FMU3Slave)
                # the shim's structure holds fmpy's fmi3 instance
                assert inst.slave._adapter.instance == inst.slave.slave.component
                assert comps[i] == inst.slave.component
    finally:
        sim.close()


@pytest.mark.parametrize("scenario", ["default", "sec53-literal"])
def test_results_csv_is_the_same_bytes_with_and_without_the_c_loop(
    fmus, scenario, tmp_path, monkeypatch
):
    seen = []
    orig = CoSimulation._plan_calls

    def spy(self):
        orig(self)
        seen.append(self._fast is not None)

    monkeypatch.setattr(CoSimulation, "_plan_calls", spy)
    runs = {}
    for fast in ("1", "0"):
        monkeypatch.setenv("GLIDER_COSIM_FASTLOOP", fast)
        out = tmp_path / f"fastloop-{fast}"
        runs[fast] = simulate(scenario, out, fmu_dir=fmus, build=False, plots=False)
    assert seen == [True, False]
    a, b = (tmp_path / f"fastloop-{f}" / "results.csv" for f in ("1", "0"))
    assert a.read_bytes() == b.read_bytes()
    assert runs["1"].status == runs["0"].status
    assert runs["1"].status == ("ok" if scenario == "default" else "stopped")
    if scenario == "sec53-literal":  # the stall: a Discard on both paths, same message
        assert len(runs["0"].data) == 491 and runs["1"].message == runs["0"].message


def test_a_users_fmu_is_validated_by_fmpy_and_the_cache_is_not(native_dir, tmp_path):
    fmu = native_dir / "GliderController.fmu"
    assert in_cache(fmu)
    user = tmp_path / "GliderController.fmu"
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(user, "w") as dst:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "modelDescription.xml":  # an attribute FMI 2.0 has not
                data = data.replace(b'<ScalarVariable name="V_hat"',
                                    b'<ScalarVariable name="V_hat" unknown="1"', 1)  # fmt: skip
            dst.writestr(info, data)
    assert not in_cache(user)
    assert read_fmu(user, None, schema=False).modelName == "GliderController"
    with pytest.raises(InputFileError, match="has no readable model description .*unknown"):
        read_fmu(user, "instance c")
    with pytest.raises(SystemSpecError, match="instance c: FMU 'GliderController.fmu' has no"):
        Instance("c", user)
    assert Instance("c", fmu).md.modelName == "GliderController"
