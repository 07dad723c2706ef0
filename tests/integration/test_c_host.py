"""A minimal C host (compiled here with gcc against the FMI 2.0 headers fmpy ships) loads
and steps GliderPlant.fmu with the environment from `glider-cosim host-env`."""

from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy
import pytest
from fmpy import read_model_description

from glider_cosim.hostenv import host_env
from glider_cosim.master import CoSimulation, System
from glider_cosim.runner import ArrayRecorder

pytestmark = pytest.mark.integration
HOST_C = Path(__file__).parent / "c_host" / "host.c"


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    if shutil.which("gcc") is None:
        pytest.fail("gcc is needed for the C host test")
    out = tmp_path_factory.mktemp("c_host") / "host"
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(["gcc", "-O1", "-o", str(out), str(HOST_C), f"-I{headers}", "-ldl"],
                   check=True, capture_output=True)  # fmt: skip
    return out


def test_c_host_runs_the_plant_with_host_env(host, fmu_dir, tmp_path):
    fmu = fmu_dir / "GliderPlant.fmu"
    with zipfile.ZipFile(fmu) as z:
        z.extractall(tmp_path / "fmu")
    md = read_model_description(str(fmu))
    vr = next(v.valueReference for v in md.modelVariables if v.name == "theta_g")
    env = {**os.environ, **host_env()}
    p = subprocess.run([str(host), str(tmp_path / "fmu"), md.guid, str(vr)], env=env,
                       capture_output=True, text=True, timeout=120)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    theta_g_c = float(p.stdout.strip())
    # the same plant under our master
    sim = CoSimulation(System(fmus={"plant": fmu}, connections=[],
                              driven={"plant.delta_cmd": 0.0, "plant.F_x": 0.0,
                                      "plant.F_z": 0.0, "plant.M_y": 0.0},
                              record=["plant.theta_g"]))  # fmt: skip
    rec = ArrayRecorder()
    sim.run(60.0, rec)
    sim.close()
    assert abs(theta_g_c - rec.array()[-1, 1]) < 1e-9


def test_c_host_without_host_env_fails(host, fmu_dir, tmp_path):
    fmu = fmu_dir / "GliderPlant.fmu"
    with zipfile.ZipFile(fmu) as z:
        z.extractall(tmp_path / "fmu")
    md = read_model_description(str(fmu))
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "PYTHONHOME")}
    p = subprocess.run([str(host), str(tmp_path / "fmu"), md.guid], env=env,
                       capture_output=True, text=True, timeout=120)  # fmt: skip
    assert p.returncode != 0
    assert "undefined symbol" in p.stderr
