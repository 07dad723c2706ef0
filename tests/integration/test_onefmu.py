"""One-FMU export of the closed loop: valid for fmpy, with units and exposed parameters,
quiet on a good run, runs under fmpy.simulate_fmu and libcosim and equals our master's
Jacobi run (the container delays each link by one step)."""

from __future__ import annotations

import json
import logging
import math
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from glider_cosim.interop.onefmu import EXPOSED, OneFMUError, export_one_fmu
from glider_cosim.runner import simulate
from glider_cosim.scenarios.overrides import apply_overrides, parse_sets
from glider_cosim.scenarios.scenario import load_scenario
from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

pytestmark = pytest.mark.integration
OUT = ["plant.theta_g", "controller.delta_cmd"]


def with_sets(sets: list[str]):
    """The default scenario with ``--set`` items, as the command line applies them."""
    return apply_overrides(load_scenario(None), parse_sets(sets))


@pytest.fixture(scope="module")
def loop_build(fmu_dir, tmp_path_factory) -> tuple[Path, list[str]]:
    """The default scenario's container, and what the toolbox logged while building it."""
    seen: list[str] = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            seen.append(record.getMessage())

    log = logging.getLogger("fmu_manipulation_toolbox")
    handler = Keep(logging.WARNING)
    log.addHandler(handler)
    try:
        fmu = export_one_fmu(tmp_path_factory.mktemp("onefmu") / "GliderLoop.fmu", None, fmu_dir)
    finally:
        log.removeHandler(handler)
    return fmu, seen


@pytest.fixture(scope="module")
def loop_fmu(loop_build) -> Path:
    return loop_build[0]


@pytest.fixture(scope="module")
def jacobi(fmu_dir):
    return simulate(None, None, fmu_dir=fmu_dir, build=False, coupling="jacobi")


def test_closed_loop_as_one_fmu(loop_fmu, fmu_dir, jacobi):
    assert validate_fmu(str(loop_fmu)) == []
    r = simulate_fmu(str(loop_fmu), stop_time=60.0, output_interval=0.02, output=OUT)
    assert len(r) == 3001
    th = r["plant.theta_g"]
    assert th[0] == pytest.approx(math.radians(-35.0), abs=1e-12)
    assert abs(th[-1] - equilibrium(GliderParams()).theta_g) < math.radians(0.01)
    assert np.array_equal(th, jacobi.column("plant.theta_g"))  # bit for bit
    gs = simulate(None, None, fmu_dir=fmu_dir, build=False)
    diff = np.degrees(np.abs(th - gs.column("plant.theta_g")).max())
    assert 0.1 < diff < 0.6  # 0.47 deg: one more sample of delay than Gauss-Seidel
    # the figure that `export-fmu --help` and docs/how-to/export.md give
    help_ = subprocess.run([sys.executable, "-m", "glider_cosim.cli", "export-fmu", "--help"],
                           capture_output=True, text=True, check=True).stdout  # fmt: skip
    assert f"up to {diff:.2f} deg in glide angle" in " ".join(help_.split())
    assert f"up to {diff:.2f} deg in glide angle" in " ".join(
        (Path(__file__).parents[2] / "docs" / "how-to" / "export.md").read_text().split()
    )


def test_container_initializes_as_our_master_every_value_of_every_row(loop_build, jacobi):
    # issue 46: the toolbox propagates the links in Initialization Mode in an order it
    # took for a loop (plant -> observer -> controller -> plant) until the export gave it
    # the FMUs' InitialUnknowns dependencies; our master sets the inputs there as it does,
    # so the first row is one too: observer theta_filt(0) is the measured pitch
    loop_fmu, warnings = loop_build
    assert not [w for w in warnings if "Loop" in w], warnings
    with zipfile.ZipFile(loop_fmu) as z:
        txt = z.read("resources/container.txt").decode().splitlines()
    order = txt[txt.index("# Initialization order of the embedded FMU's") + 1]
    assert order == "0 1 2"  # plant, observer, controller
    md = read_model_description(str(loop_fmu))
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    r = simulate_fmu(str(loop_fmu), stop_time=60.0, output_interval=0.02, output=outputs)
    assert len(outputs) == 16
    for name in outputs:
        assert np.array_equal(r[name], jacobi.column(name)), name  # bit for bit, t = 0 too
    assert r["observer.theta_filt"][0] == r["plant.theta_meas"][0]
    assert r["plant.theta_meas"][0] == pytest.approx(math.radians(-34.0), abs=1e-15)


def test_container_equals_our_jacobi_run_with_full_state_feedback(fmu_dir, tmp_path):
    # issue 46: with full-state feedback the controller's command at t = 0 acts on the
    # plant's initial state (set in Initialization Mode) in the container and in our
    # master alike: every row equal (before, our master's acted on the controller's start
    # inputs, the equilibrium, and every plant column differed from the first step on)
    fmu = export_one_fmu(tmp_path / "Loop.fmu", "fig2-closed-loop", fmu_dir)
    outputs = ["plant.theta_g", "plant.V", "plant.delta", "controller.delta_cmd"]
    r = simulate_fmu(str(fmu), stop_time=10.0, output_interval=0.02, output=outputs)
    ours = simulate("fig2-closed-loop", None, fmu_dir=fmu_dir, build=False,
                    coupling="jacobi", stop_time=10.0)  # fmt: skip
    for name in outputs:
        assert np.array_equal(r[name], ours.column(name)), name
    assert r["controller.delta_cmd"][0] != 0.0  # the law on -35 deg, not the equilibrium


def test_container_carries_units_and_exposes_parameters(loop_fmu, fmu_dir):
    md = read_model_description(str(loop_fmu))
    inner = {
        inst: {v.name: v for v in read_model_description(str(fmu_dir / f"{n}.fmu")).modelVariables}
        for inst, n in (("plant", "GliderPlant"), ("observer", "GliderObserver"),
                        ("controller", "GliderController"))
    }  # fmt: skip
    outer = {v.name: v for v in md.modelVariables}
    units = {u.name: u for u in md.unitDefinitions}
    assert units["rad"].displayUnits[0].name == "deg"
    assert units["rad"].displayUnits[0].factor == pytest.approx(180 / math.pi)
    checked = 0
    for name, v in outer.items():
        inst, _, var = name.partition(".")
        if inst not in inner or v.type != "Real":
            continue
        ref = inner[inst][var]
        assert (v.unit, v.displayUnit) == (ref.unit, ref.displayUnit), name
        assert v.unit is None or v.unit in units
        checked += 1
    assert checked > 20
    assert (outer["plant.theta_g"].unit, outer["plant.theta_g"].displayUnit) == ("rad", "deg")
    assert outer["plant.V"].unit == "m/s" and outer["plant.M_y"].unit == "N.m"
    assert outer["gliderplant.theta_meas"].unit == "rad"  # a link (local)
    for ref in EXPOSED:
        assert outer[ref].causality == "parameter", ref
    # start values: the scenario's (default: K_c 10, passivity, -35 deg, no noise)
    assert float(outer["controller.K_c"].start) == 10.0
    assert int(outer["controller.law"].start) == 1
    assert float(outer["plant.theta_g_0"].start) == math.radians(-35.0)
    assert float(outer["plant.noise_std"].start) == 0.0
    assert outer["plant.noise_std"].unit == "rad" and outer["plant.noise_seed"].type == "Integer"
    # the container's description is still schema-valid after the rewrite
    with zipfile.ZipFile(loop_fmu) as z:
        ET.fromstring(z.read("modelDescription.xml"))


QUIET_RUN = """
import sys
from fmpy import simulate_fmu
r = simulate_fmu(sys.argv[1], stop_time=2.0, output_interval=0.02, output=["plant.theta_g"])
print("rows", len(r))
"""


def test_a_good_run_prints_nothing(loop_fmu):
    # a subprocess: what the FMUs and the container write to the file descriptors too
    p = subprocess.run([sys.executable, "-c", QUIET_RUN, str(loop_fmu)],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert p.stdout == "rows 101\n"
    assert p.stderr == ""


MESSAGES = """
import sys
from fmpy import simulate_fmu
seen = []
def logger(env, instance, status, category, message):
    seen.append(message.decode())
try:
    simulate_fmu(sys.argv[1], stop_time=1.0, output_interval=0.02,
                 start_values={"plant.noise_seed": -5}, logger=logger)
except Exception as err:
    print("raised", type(err).__name__)
print(" | ".join(seen))
"""


def test_messages_other_than_the_start_lines_reach_the_host(loop_fmu, tmp_path):
    # an error of an embedded FMU is not swallowed by the forwarder; unpacked here, since
    # fmpy leaves its own unpacked copy behind when the run fails. In a subprocess: a
    # logger= given to simulate_fmu stays in fmpy's process-global proxy after the call
    # and would crash this process at the next FMU message (docs/how-to/toolchains.md).
    unpacked = extract(str(loop_fmu), unzipdir=str(tmp_path / "loop"))
    p = subprocess.run([sys.executable, "-c", MESSAGES, unpacked], capture_output=True,
                       text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    assert "raised FMICallException" in p.stdout
    assert "noise_seed" in p.stdout
    assert "Solver configure" not in p.stdout and "FMUContainer 'V" not in p.stdout


ALL_MESSAGES = """
import json, sys
from fmpy import simulate_fmu
seen = []
def logger(env, instance, status, category, message):
    seen.append(message.decode())
for start in ({}, {"plant.noise_seed": -5}):
    try:
        simulate_fmu(sys.argv[1], stop_time=0.1, output_interval=0.02, start_values=start,
                     debug_logging=True, logger=logger)
    except Exception as err:
        seen.append("raised " + type(err).__name__)
print(json.dumps(seen))
"""


def test_every_message_of_the_export_follows_fmis_hash_rule(loop_fmu, tmp_path):
    """What the forwarder passes to the host, logging on, in a good run and a failing one,
    read by FMI's '#' rule as FMI Library reads it (the container writes "FMU#0: ..."
    and passes the embedded FMUs' messages on)."""
    sys.path.insert(0, str(Path(__file__).parent))
    from fmi_log_rule import parse_fmi_message

    unpacked = extract(str(loop_fmu), unzipdir=str(tmp_path / "loop"))
    p = subprocess.run([sys.executable, "-c", ALL_MESSAGES, unpacked], capture_output=True,
                       text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    seen = json.loads(p.stdout.strip().splitlines()[-1])
    assert seen[-1] == "raised FMICallException"
    read = [parse_fmi_message(m, 2) for m in seen[:-1]]  # raises on a message that breaks it
    assert all(refs == [] for _, refs in read)
    texts = [t for t, _ in read]
    assert any(t.startswith("FMU#0: ") for t in texts), texts[:5]  # the container's own
    assert any("noise_seed" in t for t in texts)  # an embedded FMU's error


@pytest.mark.parametrize(
    ("start", "sets"),
    [
        ({"controller.K_c": 6.0}, ["controller.K_c=6"]),
        ({"controller.law": 2}, ["controller.law=p"]),
        (
            {"plant.theta_g_0": math.radians(-30.0), "plant.noise_std": 0.02,
             "plant.noise_seed": 7},
            ["plant.theta_g_0=-30 deg", "plant.noise_std=0.02", "plant.noise_seed=7"],
        ),
    ],
)  # fmt: skip
def test_exposed_parameter_changes_the_run_like_set(loop_fmu, fmu_dir, jacobi, start, sets):
    r = simulate_fmu(str(loop_fmu), stop_time=60.0, output_interval=0.02, output=OUT,
                     start_values=start)  # fmt: skip
    ours = simulate(with_sets(sets), None, fmu_dir=fmu_dir, build=False, coupling="jacobi")
    for name in OUT:
        assert np.array_equal(r[name], ours.column(name)), name
    assert not np.array_equal(r["plant.theta_g"], jacobi.column("plant.theta_g"))


LIBCOSIM_RUN = """
import json, sys
from libcosimpy.CosimEnums import CosimVariableType
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave

path, k_c, n = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
log_output_level(CosimLogLevel.ERROR)
ex = CosimExecution.from_step_size(20_000_000)
idx = ex.add_local_slave(CosimLocalSlave(fmu_path=path, instance_name="loop"))
refs = {v.name.decode(): v.reference for v in ex.slave_variables(idx)}
ex.real_initial_value(idx, refs["controller.K_c"], k_c)
obs = CosimObserver.create_time_series()
ex.add_observer(obs)
obs.start_time_series(idx, refs["plant.theta_g"], CosimVariableType.REAL)
assert ex.step(n)
values, steps = {}, []
for _ in range(3):
    k = len(values)
    t, got, vals = obs.time_series_real_samples(idx, refs["plant.theta_g"], k, n + 1 - k)
    values.update(zip(got, vals))
    if len(values) == n + 1:
        break
result = [values[k] for k in range(n + 1)]
del obs, ex  # free the instances before the interpreter exits
print("RESULT", json.dumps(result))
"""


@pytest.mark.parametrize("k_c", [10.0, 6.0])
def test_libcosim_runs_the_container_like_our_jacobi_master(loop_fmu, fmu_dir, k_c):
    n = 1000  # 20 s
    p = subprocess.run([sys.executable, "-c", LIBCOSIM_RUN, str(loop_fmu), str(k_c), str(n)],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    (line,) = [x for x in p.stdout.splitlines() if x.startswith("RESULT ")]
    th = np.array(json.loads(line.removeprefix("RESULT ")))
    logged = (p.stdout.replace(line, "") + p.stderr).lower()
    assert "[error]" not in logged and "[warning]" not in logged, logged[-2000:]
    ours = simulate(with_sets([f"controller.K_c={k_c}"]), None, fmu_dir=fmu_dir, build=False,
                    coupling="jacobi", stop_time=20.0)  # fmt: skip
    assert np.array_equal(th, ours.column("plant.theta_g"))


def test_one_fmu_export_refuses_events(fmu_dir, tmp_path):
    with pytest.raises(OneFMUError, match=r"sec53-protocol.toml: key 'event'"):
        export_one_fmu(tmp_path / "x.fmu", "sec53-protocol", fmu_dir)
