"""SSP export/import, libcosim against our master, malformed SSPs."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from fmpy.ssp.ssd import read_ssd

from glider_cosim.runner import simulate
from glider_cosim.ssp import SSPError, export_ssp, load_ssp

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def ssp(fmu_dir, tmp_path_factory):
    return export_ssp(tmp_path_factory.mktemp("ssp") / "glider.ssp", None, fmu_dir)


def test_export_is_valid_ssp_with_fmus_and_step(ssp):
    read_ssd(str(ssp), validate=True)  # fmpy's SSP 1.0 schema validation
    with zipfile.ZipFile(ssp) as z:
        names = set(z.namelist())
        ssd = z.read("SystemStructure.ssd").decode()
    assert {f"resources/{n}.fmu" for n in ("GliderPlant", "GliderObserver",
                                           "GliderController")} <= names  # fmt: skip
    assert re.search(r'<osp:FixedStepAlgorithm baseStepSize="0.02"', ssd)
    assert 'stopTime="60.0"' in ssd
    system, step, stop = load_ssp(ssp)
    assert (step, stop) == (0.02, 60.0)
    assert system.parameters["controller"] == {"law": 1, "K_c": 10.0}
    assert set(system.driven) == {"plant.F_x", "plant.F_z", "plant.M_y"}


def test_our_run_of_the_ssp_equals_the_scenario_run(ssp, fmu_dir):
    a = simulate(ssp, None, stop_time=10.0)
    b = simulate(None, None, fmu_dir=fmu_dir, build=False, stop_time=10.0)
    assert a.columns == b.columns
    assert np.array_equal(a.data, b.data)


LIBCOSIM = """
import json, sys
from glider_cosim.ssp import simulate_libcosim
print(json.dumps(simulate_libcosim(sys.argv[1], ["plant.theta_g"], float(sys.argv[2]))))
"""


def test_libcosim_matches_our_jacobi_master(ssp):
    p = subprocess.run([sys.executable, "-c", LIBCOSIM, str(ssp), "20"], capture_output=True,
                       text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    lc = np.array(json.loads(p.stdout.strip().splitlines()[-1]))
    ours = simulate(ssp, None, coupling="jacobi", stop_time=20.0)
    assert lc.shape[0] == len(ours.data) == 1001
    np.testing.assert_allclose(lc[1:, 0], ours.data[1:, 0], atol=1e-12)
    # row 0: libcosim's observer has no values before the first step
    diff = np.abs(lc[1:, 1] - ours.column("plant.theta_g")[1:])
    assert diff.max() < 1e-6
    gs = simulate(ssp, None, coupling="gauss-seidel", stop_time=20.0)
    assert np.abs(lc[1:, 1] - gs.column("plant.theta_g")[1:]).max() > 1e-3  # another scheme


def edit_ssd(ssp, tmp_path, old, new, name="bad.ssp"):
    out = tmp_path / name
    with zipfile.ZipFile(ssp) as zin, zipfile.ZipFile(out, "w") as zout:
        for item in zin.namelist():
            data = zin.read(item)
            if item == "SystemStructure.ssd":
                text = data.decode()
                assert old in text
                data = text.replace(old, new, 1).encode()
            if not (old == "DROP" and item == new):
                zout.writestr(item, data)
    return out


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('baseStepSize="0.02"', 'baseStepSize="-0.02"', r"baseStepSize = '-0.02': expected a "),
        ('baseStepSize="0.02"', 'baseStepSize="fast"', r"baseStepSize 'fast' .* not a number"),
        ('startConnector="theta_meas"', 'startConnector="pitch"',
         r"connection plant.pitch -> observer.theta_meas: 'plant' has no variable 'pitch'"),
        ('name="delta_cmd" kind="input"', 'name="tail" kind="input"',
         r"component 'plant': connector 'tail' is not a variable of resources/GliderPlant.fmu"),
        ('endElement="observer"', 'endElement="estimator"', r"unknown element 'estimator'"),
        ('source="resources/GliderPlant.fmu"', 'source="resources/Missing.fmu"',
         r"component 'plant': FMU 'resources/Missing.fmu' is missing"),
    ],
)  # fmt: skip
def test_malformed_ssp_is_refused_before_any_fmu_runs(ssp, tmp_path, old, new, message):
    bad = edit_ssd(ssp, tmp_path, old, new)
    with pytest.raises(SSPError, match=message):
        load_ssp(bad)
    p = subprocess.run([sys.executable, "-m", "glider_cosim.cli", "run", str(bad)],
                       capture_output=True, text=True, timeout=120)  # fmt: skip
    assert p.returncode == 2
    assert len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr
