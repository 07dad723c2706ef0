"""FMI 3.0 FMUs (both flavors) under our master, fmpy, fmpy's FMI 3 API and a C host.

- the default and the noise scenario through our master on each FMI 3 flavor equal the
  FMI 2 runs (bit for bit), alone and mixed with FMI 2 FMUs in one system, with the C
  fast loop serving the FMI 3 instances;
- a stall is a clean stop (status "stopped") through our master;
- ``fmpy.simulate_fmu`` on every FMI 3 FMU equals the FMI 2 build;
- an invalid start value ends a host's run with fmi3Error and our message, logging off;
- fmi3GetFMUState/SetFMUState and serialization round trip, bit for bit;
- the call-sequence fuzz on FMI 3 calls: test_fmi_fuzz.py (fmi3_fuzz.py);
- ``build --fmi 3``, ``run --fmi 3``/``--fmu-dir``, ``export-ssp --fmi 3``; build_all keeps
  a folder's FMI version, and converts it only with ``overwrite`` (``--overwrite-fmus``);
- Ecos (ecospy, a test dependency) on the FMI 3 SSP, equal to our Jacobi master;
- the C host's FMI 3 path (tests/integration/c_host/host.c, -DGLIDER_HOST_FMI3) steps
  the native FMI 3 FMUs with no Python reachable and their win64 DLLs under wine, equal
  to our master, and runs clean under valgrind memcheck.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
import sys
import zipfile

import fmpy
import numpy as np
import pytest
from c_host_helpers import (
    GCC_FLAGS,
    RECORD,
    STOP,
    compile_host,
    hidden_rows,
    master_jacobi_run,
    valgrind_run,
    wine_rows,
    write_plan,
)
from fmpy.fmi3 import FMU3Slave

from glider_cosim.fmus.folders import FmuFolderError, build_all, folder_flavor, folder_fmi
from glider_cosim.master import CoSimulation
from glider_cosim.runner import simulate
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for

pytestmark = pytest.mark.integration
NAMES = ("GliderPlant", "GliderObserver", "GliderController")
FLAVORS = ("python", "native")
FMI3_HOST = ["-DGLIDER_HOST_FMI3"]


def fmi2_dir(request, flavor: str):
    return request.getfixturevalue("fmu_dir" if flavor == "python" else "native_dir")


@pytest.fixture
def fast_loop_seen(monkeypatch):
    """The FMI versions and fast-loop use of every CoSimulation planned in the test."""
    seen: list[tuple[dict[str, int], bool]] = []
    orig = CoSimulation._plan_calls

    def spy(self):
        orig(self)
        seen.append(({n: i.fmi for n, i in self.instances.items()}, self._fast is not None))

    monkeypatch.setattr(CoSimulation, "_plan_calls", spy)
    return seen


@pytest.mark.parametrize("flavor", FLAVORS)
@pytest.mark.parametrize("scenario", ["default", "fig5-6-observer-noise"])
def test_master_on_fmi3_equals_fmi2_bit_for_bit(
    request, fmi3_dirs, flavor, scenario, fast_loop_seen
):
    assert folder_fmi(fmi3_dirs[flavor]) == 3
    a = simulate(scenario, None, fmu_dir=fmi2_dir(request, flavor), build=False)
    b = simulate(scenario, None, fmu_dir=fmi3_dirs[flavor], build=False)
    assert a.status == b.status == "ok"
    assert a.columns == b.columns and a.data.shape == b.data.shape == (3001, len(a.columns))
    diff = np.abs(a.data - b.data).max()
    print(f"{scenario} {flavor}: max |FMI 3 - FMI 2| = {diff:.3g}")
    assert diff <= 1e-9  # the bound
    assert np.array_equal(a.data, b.data)  # what we reach: bit for bit
    versions, fast = fast_loop_seen[-1]
    assert set(versions.values()) == {3} and fast  # the C fast loop served FMI 3


def test_mixed_system_fmi3_plant_fmi2_observer_and_controller(
    fmu_dir, native_dir, fmi3_dirs, fast_loop_seen
):
    sc = load_scenario("default")
    a = simulate(sc, None, fmu_dir=fmu_dir, build=False)
    for plant_dir, ctrl_dir in [(fmi3_dirs["native"], fmu_dir), (fmi3_dirs["python"], native_dir)]:
        swaps = {
            "plant": str(plant_dir / "GliderPlant.fmu"),
            "controller": str(ctrl_dir / "GliderController.fmu"),
        }
        b = simulate(dataclasses.replace(sc, fmus=swaps), None, fmu_dir=fmu_dir, build=False)
        assert b.status == "ok"
        assert np.array_equal(a.data, b.data)
        versions, fast = fast_loop_seen[-1]
        assert versions == {"plant": 3, "observer": 2, "controller": 2} and fast


@pytest.mark.parametrize("flavor", FLAVORS)
def test_stall_through_our_master_is_a_clean_stop(request, fmi3_dirs, flavor):
    a = simulate("sec53-literal", None, fmu_dir=fmi2_dir(request, flavor), build=False)
    b = simulate("sec53-literal", None, fmu_dir=fmi3_dirs[flavor], build=False)
    assert a.status == b.status == "stopped"
    assert "observer: fmi3DoStep at t = 9.8 s returned fmi3Discard" in b.message
    assert "glider stalled: V = " in b.message
    assert np.array_equal(a.data, b.data) and len(b.data) == 491


@pytest.mark.parametrize("flavor", FLAVORS)
def test_invalid_start_value_through_our_master_is_fmi3error(fmu_dir, fmi3_dirs, flavor):
    sc = load_scenario("default")
    sc = dataclasses.replace(
        sc,
        fmus={"controller": str(fmi3_dirs[flavor] / "GliderController.fmu")},
        parameters={**sc.parameters, "controller": {"K_c": -1.0}},
    )
    r = simulate(sc, None, fmu_dir=fmu_dir, build=False)
    assert r.status == "error"
    assert (
        "controller: fmi3GetFloat64(delta_cmd) in Initialization Mode at t = 0 s returned "
        "fmi3Error: "
        "[fmi3Error] K_c = -1.0 is invalid: expected a finite value in (0, inf)"
    ) in r.message


@pytest.mark.parametrize("flavor", FLAVORS)
@pytest.mark.parametrize("name", NAMES)
def test_fmpy_simulate_fmu_on_fmi3_equals_fmi2(request, fmi3_dirs, flavor, name):
    fmu3 = fmi3_dirs[flavor] / f"{name}.fmu"
    fmu2 = fmi2_dir(request, flavor) / f"{name}.fmu"
    a = fmpy.simulate_fmu(str(fmu3), stop_time=5.0, output_interval=0.02)
    b = fmpy.simulate_fmu(str(fmu2), stop_time=5.0, output_interval=0.02)
    assert len(a) == len(b) == 251
    assert a.dtype.names == b.dtype.names
    for col in a.dtype.names:
        assert np.array_equal(a[col], b[col]), col


def slave3(fmu, tmp_path, name: str = "x", log: list | None = None) -> FMU3Slave:
    md = fmpy.read_model_description(str(fmu))
    folder = tmp_path / f"{fmu.stem}_{name}"
    if not folder.is_dir():
        with zipfile.ZipFile(fmu) as z:
            z.extractall(folder)
    s = FMU3Slave(guid=md.guid, unzipDirectory=str(folder),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)  # fmt: skip
    sink = log if log is not None else []
    s.instantiate(loggingOn=False, logMessage=lambda env, st, cat, msg: sink.append((st, msg)))
    s.md = md
    return s


@pytest.mark.parametrize("flavor", FLAVORS)
def test_invalid_start_value_ends_an_fmpy_fmi3_host_with_fmi3error(fmi3_dirs, tmp_path, flavor):
    log: list = []
    s = slave3(fmi3_dirs[flavor] / "GliderController.fmu", tmp_path, log=log)
    vr = {v.name: v.valueReference for v in s.md.modelVariables}
    s.enterInitializationMode(startTime=0.0)
    s.setFloat64([vr["K_c"]], [-1.0])
    with pytest.raises(fmpy.fmi1.FMICallException) as err:
        s.exitInitializationMode()
    assert err.value.status == 3  # fmi3Error
    msg = b"fmi3ExitInitializationMode: K_c = -1.0 is invalid: expected a finite value in (0, inf)"
    assert (3, b"x: " + msg) in log  # FMI 3's logger is not told the instance: the text is
    s.freeInstance()


@pytest.mark.parametrize("flavor", FLAVORS)
def test_after_an_error_the_messages_name_fmi3_functions_in_whole_sentences(
    fmi3_dirs, tmp_path, flavor
):
    """Issue 54: the FMI 3.0 front end's messages name FMI 3.0 functions (the layer knows
    which front end was called), and the sentence after an error is whole."""
    log: list = []
    s = slave3(fmi3_dirs[flavor] / "GliderController.fmu", tmp_path, log=log)
    vr = {v.name: v.valueReference for v in s.md.modelVariables}
    s.enterInitializationMode(startTime=0.0)
    s.setFloat64([vr["K_c"]], [-1.0])
    with pytest.raises(fmpy.fmi1.FMICallException):
        s.exitInitializationMode()
    for call in (lambda: s.enterInitializationMode(startTime=0.0),
                 lambda: s.doStep(0.0, 0.02), lambda: s.terminate()):  # fmt: skip
        with pytest.raises(fmpy.fmi1.FMICallException):
            call()
    texts = [msg.decode() for _, msg in log]
    assert texts[-3:] == [
        f"x: {name}: not allowed after an error: only getters, FMU-state functions, "
        "fmi3Reset and fmi3FreeInstance are allowed then"
        for name in ("fmi3EnterInitializationMode", "fmi3DoStep", "fmi3Terminate")
    ]
    assert not [t for t in texts if "fmi2" in t], texts
    s.freeInstance()


def _plant_steps(s: FMU3Slave, vrs: list[int], t0: float, n: int) -> list[list[float]]:
    out = []
    for k in range(n):
        s.doStep(t0 + k * 0.02, 0.02)
        out.append(s.getFloat64(vrs))
    return out


@pytest.mark.parametrize("flavor", FLAVORS)
def test_fmu_state_and_serialization_round_trip_bit_for_bit(fmi3_dirs, tmp_path, flavor):
    fmu = fmi3_dirs[flavor] / "GliderPlant.fmu"
    a = slave3(fmu, tmp_path, "a")
    outs = [v.valueReference for v in a.md.modelVariables if v.causality == "output"]
    a.enterInitializationMode(startTime=0.0)
    a.exitInitializationMode()
    a.setFloat64([v.valueReference for v in a.md.modelVariables if v.name == "delta_cmd"], [0.05])
    _plant_steps(a, outs, 0.0, 100)
    state = a.getFMUState()
    blob = a.serializeFMUState(state)
    ahead = _plant_steps(a, outs, 2.0, 100)
    a.setFMUState(state)  # back to t = 2 s in the same instance
    assert _plant_steps(a, outs, 2.0, 100) == ahead
    b = slave3(fmu, tmp_path, "b")
    b.enterInitializationMode(startTime=0.0)
    b.exitInitializationMode()
    restored = b.deserializeFMUState(blob)
    b.setFMUState(restored)
    assert _plant_steps(b, outs, 2.0, 100) == ahead  # bit for bit in a fresh instance
    b.freeFMUState(restored)
    a.freeFMUState(state)
    for s in (a, b):
        s.terminate()
        s.freeInstance()


# ---------------------------------------------------------------- the C host, FMI 3
@pytest.fixture(scope="module")
def fmi3_system(fmi3_dirs):
    return system_for(load_scenario("default"), fmi3_dirs["native"])


@pytest.fixture(scope="module")
def fmi3_master_rows(fmi3_system, native_dir) -> np.ndarray:
    got = master_jacobi_run(fmi3_system).array()
    fmi2 = system_for(load_scenario("default"), native_dir)
    assert np.array_equal(got, master_jacobi_run(fmi2).array())
    return got


def test_c_host_fmi3_with_no_python_reachable_equals_our_master(
    fmi3_system, fmi3_master_rows, tmp_path
):
    got = hidden_rows(fmi3_system, tmp_path, "host3", FMI3_HOST)
    assert got.shape == fmi3_master_rows.shape == (round(STOP / 0.02) + 1, 1 + len(RECORD))
    assert np.array_equal(got, fmi3_master_rows)  # bit for bit


def test_c_host_fmi3_invalid_start_value_is_fmi3error_with_our_message(fmi3_system, tmp_path):
    host = compile_host("gcc", tmp_path / "host3", [*FMI3_HOST, *GCC_FLAGS])
    system = dataclasses.replace(
        fmi3_system,
        parameters={**fmi3_system.parameters, "controller": {"K_c": -1.0}},
    )
    plan = write_plan(system, tmp_path)
    p = subprocess.run([str(host), str(plan)], capture_output=True, text=True, timeout=120)
    assert p.returncode == 5  # initialisation failed
    assert "status 3" in p.stderr and "K_c = -1.0 is invalid" in p.stderr, p.stderr


def test_c_host_fmi3_win64_dlls_under_wine_equal_linux64(fmi3_system, fmi3_master_rows, tmp_path):
    got = wine_rows(fmi3_system, tmp_path, "host3.exe", FMI3_HOST)
    assert got.shape == fmi3_master_rows.shape
    diff = np.abs(got - fmi3_master_rows).max()
    print(f"FMI 3 win64 under wine vs linux64: max diff {diff:.3g}")
    assert diff <= 1e-9


# ---------------------------------------------------------------- the CLI
def cli(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-c", "from glider_cosim.cli import console_main; console_main()", *args],
        capture_output=True, text=True, cwd=cwd, timeout=300,
    )  # fmt: skip


def test_cli_build_run_and_export_ssp_with_fmi3(tmp_path):
    p = cli("build", "--fmi", "3", "--flavor", "native", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    folder = tmp_path / "fmus" / "fmi3" / "native"
    assert folder_fmi(folder) == 3 and folder_flavor(folder) == "native"
    # run --fmi 3 --flavor native uses that set; --fmu-dir takes it as it is
    for args in (["--fmi", "3", "--flavor", "native"], ["--fmu-dir", str(folder)]):
        p = cli("run", "--no-plots", "--stop-time", "2", "--out", "o", *args, cwd=tmp_path)
        assert p.returncode == 0, p.stderr
    assert folder_fmi(folder) == 3  # not rebuilt as FMI 2
    p = cli("export-ssp", "x.ssp", "--fmi", "3", "--flavor", "native", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    with zipfile.ZipFile(tmp_path / "x.ssp") as z:
        ssd = z.read("SystemStructure.ssd").decode()
        for name in NAMES:
            z.extract(f"resources/{name}.fmu", tmp_path / "ssp")
    assert folder_fmi(tmp_path / "ssp" / "resources") == 3
    # SSP 2.0: FMI 3's Float64 connectors as they are
    assert 'version="2.0"' in ssd and ssd.count("<ssc:Float64") >= 10 and "<ssc:Real" not in ssd
    p = cli("run", "x.ssp", "--no-plots", "--stop-time", "2", "--out", "s", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    a = np.loadtxt(tmp_path / "o" / "results.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(tmp_path / "s" / "results.csv", delimiter=",", skiprows=1)
    assert a.shape == b.shape and np.array_equal(a, b)
    p = cli("export-fmu", "one.fmu", "--fmu-dir", str(folder), cwd=tmp_path)
    assert p.returncode == 2 and "holds FMI 3.0 FMUs: the one-FMU export takes FMI 2.0" in p.stderr


def test_build_all_keeps_a_folder_fmi3_and_converts_it_only_when_told(fmi3_dirs, tmp_path):
    folder = tmp_path / "n"
    shutil.copytree(fmi3_dirs["native"], folder)
    build_all(folder, only_stale=True)
    assert folder_fmi(folder) == 3 and folder_flavor(folder) == "native"
    with pytest.raises(FmuFolderError, match="holds FMI 3.0 native FMUs .*, not the FMI 2.0 "
                       "native ones asked for: a set is not converted in place"):  # fmt: skip
        build_all(folder, only_stale=True, fmi=2)
    assert folder_fmi(folder) == 3
    build_all(folder, only_stale=True, fmi=2, overwrite=True)  # --overwrite-fmus
    assert folder_fmi(folder) == 2 and folder_flavor(folder) == "native"


@pytest.mark.parametrize("shims", ["c", "python"])
def test_integer_and_boolean_values_through_the_shims(
    fmu_dir, fmi3_dirs, monkeypatch, fast_loop_seen, shims
):
    """Int32 and Boolean variables set and recorded through the FMI 3 adapter and its
    shims (C, or the Python stand-ins used without a C compiler), equal to FMI 2."""
    import glider_cosim.master.fmi3 as fmi3_slave

    if shims == "python":
        monkeypatch.setattr(fmi3_slave, "shim_library", lambda hold_gil: None)
    sc = load_scenario("default")
    record = ["plant.theta_g", "controller.law", "observer.start_at_equilibrium",
              "plant.noise_seed"]  # fmt: skip
    params = {**sc.parameters, "observer": {**sc.parameters.get("observer", {}),
                                            "start_at_equilibrium": False}}  # fmt: skip
    sc = dataclasses.replace(sc, record=record, parameters=params, stop_time=10.0)
    a = simulate(sc, None, fmu_dir=fmu_dir, build=False)
    b = simulate(sc, None, fmu_dir=fmi3_dirs["native"], build=False)
    assert a.status == b.status == "ok"
    assert np.array_equal(a.data, b.data)
    assert set(b.data[:, 2]) == {1.0} and set(b.data[:, 3]) == {0.0}  # law 1, False
    assert fast_loop_seen[-1][0] == {"plant": 3, "observer": 3, "controller": 3}


def test_the_fmpy_path_without_a_compiler_equals_the_c_shims(native_dir, fmi3_dirs, monkeypatch):
    # no C compiler: no shims, no fast loop; FMU3Slave's own methods step the FMI 3 FMUs
    import glider_cosim.master.fmi3 as fmi3_slave

    a = simulate("default", None, fmu_dir=native_dir, build=False)
    monkeypatch.setattr(fmi3_slave, "shim_library", lambda hold_gil: None)
    b = simulate("default", None, fmu_dir=fmi3_dirs["native"], build=False)
    c = simulate("sec53-literal", None, fmu_dir=fmi3_dirs["native"], build=False)
    assert a.status == b.status == "ok" and np.array_equal(a.data, b.data)
    assert c.status == "stopped" and len(c.data) == 491  # the stall, through Python too


def test_c_host_fmi3_run_is_clean_under_valgrind(fmi3_system, tmp_path):
    p = valgrind_run(fmi3_system, tmp_path, "host3", FMI3_HOST)
    assert p.returncode == 0, p.stderr[-3000:]
    assert "ERROR SUMMARY: 0 errors" in p.stderr
    assert "definitely lost: 0 bytes" in p.stderr or "no leaks are possible" in p.stderr


ECOS_SCRIPT = """
import json, sys
from ecospy import EcosSimulation
sim = EcosSimulation(step_size=0.02, ssp_path=sys.argv[1])
sim.init()
rows = [sim.get_real("plant::theta_g")]
for _ in range(1000):
    sim.step()
    rows.append(sim.get_real("plant::theta_g"))
sim.terminate()
sim.free()
print(json.dumps(rows))
"""


def test_ecos_runs_the_fmi3_ssp_equal_to_our_jacobi_master(fmi3_dirs, tmp_path):
    """Ecos (ecospy, a test dependency; its library needs Debian's libtbb12, which
    ``.ci/run`` installs) on the SSP of the native FMI 3 FMUs, in a subprocess (it steps
    on its own thread pool). Ecos 0.7.2 reads only SSP 1.0 (its parser refuses any other
    version): it refuses the default SSP 2.0 export and runs the ``ssp_version="1.0"``
    one (``export-ssp --ssp-version 1.0``)."""
    import json

    from glider_cosim.interop.ssp_export import export_ssp
    from glider_cosim.runner import run_ssp

    ssp2 = export_ssp(tmp_path / "glider3-2.ssp", None, fmi3_dirs["native"])
    ssp = export_ssp(tmp_path / "glider3.ssp", None, fmi3_dirs["native"], ssp_version="1.0")
    scratch = tmp_path / "ecos_tmp"  # Ecos leaves its unpacked SSP in $TMPDIR
    scratch.mkdir()
    env = {**os.environ, "TMPDIR": str(scratch)}
    p = subprocess.run([sys.executable, "-c", ECOS_SCRIPT, str(ssp2)], capture_output=True,
                       text=True, timeout=300, env=env)  # fmt: skip
    assert p.returncode != 0 and "Unsupported SSP version: '2.0'" in p.stderr, p.stderr[-2000:]
    p = subprocess.run([sys.executable, "-c", ECOS_SCRIPT, str(ssp)], capture_output=True,
                       text=True, timeout=300, env=env)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    ecos = np.array(json.loads(p.stdout.strip().splitlines()[-1]))
    ours = run_ssp(ssp, None, coupling="jacobi", stop_time=20.0).column("plant.theta_g")
    assert np.array_equal(ours, run_ssp(ssp2, None, coupling="jacobi", stop_time=20.0)
                          .column("plant.theta_g"))  # fmt: skip
    assert ecos.shape == ours.shape == (1001,)
    print(f"Ecos on FMI 3 vs our jacobi master: max |d theta_g| = {np.abs(ecos - ours).max():.3g}")
    assert np.array_equal(ecos, ours)
