"""SSP export and import; libcosim against our master on the same SSP; malformed SSPs."""

from __future__ import annotations

import math
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
from fmpy.ssp.ssd import read_ssd

from glider_cosim.interop.libcosim import simulate_libcosim_isolated
from glider_cosim.interop.ssp_common import NS
from glider_cosim.interop.ssp_export import export_ssp
from glider_cosim.interop.ssp_import import SSPError, load_ssp
from glider_cosim.runner import run_ssp, simulate
from glider_cosim.scenarios.system import default_connections

pytestmark = pytest.mark.integration
FMUS = ("GliderPlant", "GliderObserver", "GliderController")


@pytest.fixture(scope="module")
def ssp(flavor_dir: Path, tmp_path_factory) -> Path:
    """The default scenario as an SSP archive, with the FMUs of each flavor in turn."""
    return export_ssp(tmp_path_factory.mktemp("ssp") / "glider.ssp", None, flavor_dir)


@pytest.fixture(scope="module")
def libcosim_20s(ssp: Path):
    """libcosim's run of the default SSP over 20 s (in a subprocess)."""
    return simulate_libcosim_isolated(
        ssp, ["plant.theta_g", "controller.delta_cmd"], stop_time=20.0, timeout=300
    )


def ssd_text(ssp: Path) -> str:
    with zipfile.ZipFile(ssp) as z:
        return z.read("SystemStructure.ssd").decode()


def test_export_is_schema_valid_ssp_with_fmus_step_and_parameters(ssp):
    read_ssd(str(ssp), validate=True)  # fmpy's SSP 1.0 XSDs
    with zipfile.ZipFile(ssp) as z:
        assert {f"resources/{n}.fmu" for n in FMUS} <= set(z.namelist())
    root = ET.fromstring(ssd_text(ssp))
    # where libcosim's ssp_parser reads the step: DefaultExperiment's OSP annotation
    exp = root.find("ssd:DefaultExperiment", NS)
    assert (exp.get("startTime"), exp.get("stopTime")) == ("0.0", "60.0")
    (ann,) = exp.findall("ssd:Annotations/ssc:Annotation", NS)
    assert ann.get("type") == "com.opensimulationplatform"
    (alg,) = ann.findall("osp:Algorithm/osp:FixedStepAlgorithm", NS)
    assert alg.get("baseStepSize") == "0.02"
    comps = root.findall("ssd:System/ssd:Elements/ssd:Component", NS)
    assert {c.get("name"): c.get("source") for c in comps} == {
        "plant": "resources/GliderPlant.fmu",
        "observer": "resources/GliderObserver.fmu",
        "controller": "resources/GliderController.fmu",
    }
    conns = [
        (f"{c.get('startElement')}.{c.get('startConnector')}",
         f"{c.get('endElement')}.{c.get('endConnector')}")
        for c in root.findall("ssd:System/ssd:Connections/ssd:Connection", NS)
    ]  # fmt: skip
    assert conns == default_connections("observer")
    system, step, stop = load_ssp(ssp)
    assert (step, stop) == (0.02, 60.0)
    assert system.connections == conns
    assert system.parameters["controller"] == {"law": 1, "K_c": 10.0}
    assert system.parameters["plant"]["theta_g_0"] == math.radians(-35.0)
    # the unconnected disturbance inputs are driven at their start value 0
    assert system.driven == {"plant.F_x": 0.0, "plant.F_z": 0.0, "plant.M_y": 0.0}


def test_folder_and_ssd_file_load_like_the_archive(ssp, tmp_path):
    with zipfile.ZipFile(ssp) as z:
        z.extractall(tmp_path)
    a, *rest_a = load_ssp(ssp)
    for other in (tmp_path, tmp_path / "SystemStructure.ssd"):
        b, *rest_b = load_ssp(other)
        assert (b.parameters, b.connections, b.driven, rest_b) == (
            a.parameters,
            a.connections,
            a.driven,
            rest_a,
        )
        assert set(b.fmus) == set(a.fmus)
    assert load_ssp(ssp)[0].fmus == a.fmus  # an archive is unpacked once per process


def test_our_run_of_the_ssp_equals_the_scenario_run(ssp, flavor_dir):
    a = run_ssp(ssp, None, stop_time=10.0)
    b = simulate(None, None, fmu_dir=flavor_dir, build=False, stop_time=10.0)
    assert a.status == "ok" and a.columns == b.columns
    assert np.array_equal(a.data, b.data)


def test_libcosim_equals_our_jacobi_master(ssp, libcosim_20s):
    lc = libcosim_20s
    ours = run_ssp(ssp, None, coupling="jacobi", stop_time=20.0)
    assert lc.data.shape == (1001, 3) and len(ours.data) == 1001
    np.testing.assert_allclose(lc.column("time"), ours.column("time"), rtol=0, atol=1e-12)
    diff = np.abs(lc.column("plant.theta_g") - ours.column("plant.theta_g"))
    print(f"libcosim vs our jacobi: max |d theta_g| = {diff.max():.3g} rad over 20 s")
    assert diff.max() < 1e-15  # libcosim steps the instances on its thread pool
    # the first steps, the initial point included
    np.testing.assert_allclose(
        lc.column("controller.delta_cmd")[:5], ours.column("controller.delta_cmd")[:5], atol=1e-12
    )
    assert lc.column("controller.delta_cmd")[1] == 0.0  # jacobi: one more sample of delay
    assert lc.seconds_per_step > 0


def test_libcosim_against_our_gauss_seidel(ssp, libcosim_20s):
    gs = run_ssp(ssp, None, coupling="gauss-seidel", stop_time=20.0)
    diff = np.abs(libcosim_20s.column("plant.theta_g") - gs.column("plant.theta_g"))
    print(f"libcosim vs our gauss-seidel: max |d theta_g| = {math.degrees(diff.max()):.3f} deg")
    # another scheme: the controller acts one sample earlier in Gauss-Seidel
    assert math.radians(0.1) < diff.max() < math.radians(1.0)
    assert gs.column("controller.delta_cmd")[1] != 0.0


def edit_ssd(ssp: Path, tmp_path: Path, old: str, new: str, drop: str | None = None) -> Path:
    """A copy of ``ssp`` with one text replacement in its SSD (and a member dropped)."""
    out = tmp_path / "bad.ssp"
    with zipfile.ZipFile(ssp) as zin, zipfile.ZipFile(out, "w") as zout:
        for item in zin.namelist():
            data = zin.read(item)
            if item == "SystemStructure.ssd":
                text = data.decode()
                assert old in text, old
                data = text.replace(old, new, 1).encode()
            if item != drop:
                zout.writestr(item, data)
    return out


CONTROLLER_PARAMETER = '<ssv:Parameter name="K_c">'
MALFORMED = [
    ('baseStepSize="0.02"', 'baseStepSize="-0.02"',
     r"osp:FixedStepAlgorithm baseStepSize = '-0.02' is invalid: expected a number > 0"),
    ('baseStepSize="0.02"', 'baseStepSize="fast"', r"baseStepSize = 'fast' is invalid"),
    ('<osp:FixedStepAlgorithm baseStepSize="0.02" />', "",
     r"no communication step \(no osp:FixedStepAlgorithm, .*\): give one with --step"),
    ('stopTime="60.0"', 'stopTime="0"', r"ssd:DefaultExperiment stopTime = '0' is invalid"),
    ('startConnector="theta_meas"', 'startConnector="pitch"',
     r"connection plant.pitch -> observer.theta_meas: 'plant' \(resources/GliderPlant.fmu\) "
     r"has no variable 'pitch'"),
    ('endConnector="delta_cmd"', 'endConnector="delta"',
     r"connection controller.delta_cmd -> plant.delta: plant.delta is output: expected input"),
    ('name="delta_cmd" kind="input"', 'name="tail" kind="input"',
     r"component 'plant': connector 'tail' is not a variable of resources/GliderPlant.fmu"),
    ('endElement="observer"', 'endElement="estimator"',
     r"connection plant.theta_meas -> estimator.theta_meas: unknown element 'estimator'"),
    ('source="resources/GliderPlant.fmu"', 'source="resources/Missing.fmu"',
     r"component 'plant': FMU 'resources/Missing.fmu' is missing"),
    (CONTROLLER_PARAMETER, '<ssv:Parameter name="K_cc">',
     r"component 'controller': parameter 'K_cc' is not a variable of "),
    ('<ssv:Integer value="1" />', '<ssv:Real value="1.0" />',
     r"component 'controller': parameter 'law' is given as Real but is Integer"),
]  # fmt: skip


@pytest.mark.parametrize(("old", "new", "message"), MALFORMED)
def test_malformed_ssp_is_refused_with_one_line(ssp, tmp_path, old, new, message):
    bad = edit_ssd(ssp, tmp_path, old, new)
    with pytest.raises(SSPError, match=message) as err:
        load_ssp(bad)
    assert "\n" not in str(err.value) and str(err.value).startswith(str(bad))


def test_missing_fmu_member_is_refused(ssp, tmp_path):
    bad = edit_ssd(ssp, tmp_path, "<ssd:System", "<ssd:System", drop="resources/GliderObserver.fmu")
    with pytest.raises(SSPError, match=r"component 'observer': FMU .* is missing"):
        load_ssp(bad)


def test_unknown_connection_is_refused_before_any_fmu_is_instantiated(ssp, tmp_path, monkeypatch):
    from fmpy.fmi2 import FMU2Slave

    calls = []
    monkeypatch.setattr(FMU2Slave, "instantiate", lambda *a, **k: calls.append(a))
    bad = edit_ssd(ssp, tmp_path, 'startConnector="theta_meas"', 'startConnector="pitch"')
    with pytest.raises(SSPError, match="has no variable 'pitch'"):
        run_ssp(bad)
    assert calls == []


def test_cli_refuses_a_malformed_ssp_with_one_line_and_exit_2(ssp, tmp_path):
    bad = edit_ssd(ssp, tmp_path, 'baseStepSize="0.02"', 'baseStepSize="0"')
    p = subprocess.run(
        [sys.executable, "-m", "glider_cosim.cli", "run", str(bad), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 2, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr
    assert "baseStepSize = '0' is invalid" in p.stderr


def test_libcosim_initial_propagation(ssp, tmp_path):
    # the controller's connected input theta_g_hat starts at -0.5 rad, not at the
    # observer's initial estimate (the equilibrium, -0.394 rad): libcosim and our master
    # (issue 46) both set it from the observer in Initialization Mode (an expected failure
    # before, when ours read the command from the input's start value at t0)
    bound = edit_ssd(
        ssp,
        tmp_path,
        CONTROLLER_PARAMETER,
        '<ssv:Parameter name="theta_g_hat"><ssv:Real value="-0.5" /></ssv:Parameter>'
        + CONTROLLER_PARAMETER,
    )
    lc = simulate_libcosim_isolated(bound, ["controller.delta_cmd"], stop_time=0.1, timeout=300)
    ours = run_ssp(bound, None, coupling="jacobi", stop_time=0.1)
    # the controller sees the observer's estimate before t0 (command 0) in both
    assert lc.column("controller.delta_cmd")[0] == ours.column("controller.delta_cmd")[0]
