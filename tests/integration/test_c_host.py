"""A C host loads our pythonfmu FMU with the environment from ``glider-cosim host-env``.

tests/integration/c_host/host.c is compiled here with gcc against the FMI 2.0 headers
fmpy ships; it dlopens GliderPlant's binary, instantiates it with a logger callback,
initialises it, steps it 60 s at 0.02 s with the tail command and the disturbances at 0,
and prints the glide angle. Without the environment the binary cannot even be loaded
(pythonfmu binaries use the host process's Python C API)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import pytest
from fmpy import read_model_description

from glider_cosim.hostenv import host_env, libpython
from glider_cosim.master import CoSimulation, System
from glider_cosim.runner import ArrayRecorder

pytestmark = pytest.mark.integration
HOST_C = Path(__file__).parent / "c_host" / "host.c"
INPUTS = ("delta_cmd", "F_x", "F_z", "M_y")
HOST_VARS = ("LD_PRELOAD", "PYTHONPATH", "PYTHONHOME")


@pytest.fixture(scope="module")
def host(tmp_path_factory) -> Path:
    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.fail("gcc is needed to compile the C host")
    out = tmp_path_factory.mktemp("c_host") / "host"
    headers = Path(fmpy.__file__).parent / "c-code"
    assert (headers / "fmi2Functions.h").is_file()
    p = subprocess.run(
        [gcc, "-std=c99", "-D_DEFAULT_SOURCE", "-Wall", "-Wextra", "-Werror", "-O1",
         f"-I{headers}", "-o", str(out), str(HOST_C), "-ldl", "-lm"],
        capture_output=True,
        text=True,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    return out


@pytest.fixture(scope="module")
def plant(fmu_dir, tmp_path_factory) -> tuple[Path, list[str]]:
    """The unzipped GliderPlant.fmu and the host's arguments after the folder."""
    fmu = fmu_dir / "GliderPlant.fmu"
    folder = tmp_path_factory.mktemp("plant_fmu")
    with zipfile.ZipFile(fmu) as z:
        z.extractall(folder)
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    args = [md.coSimulation.modelIdentifier, md.guid, "60", "0.02", str(vr["theta_g"])]
    args += [f"{vr[name]}=0" for name in INPUTS]
    return folder, args


def master_theta_g(fmu: Path) -> float:
    """theta_g(60 s) of the plant alone under our master (same inputs)."""
    system = System(
        fmus={"plant": fmu},
        connections=[],
        driven={f"plant.{name}": 0.0 for name in INPUTS},
        record=["plant.theta_g"],
    )
    sim = CoSimulation(system)
    rec = ArrayRecorder()
    try:
        sim.run(60.0, rec)
    finally:
        sim.close()
    data = rec.array()
    assert data[-1, 0] == pytest.approx(60.0)
    return float(data[-1, 1])


def test_host_env_names_libpython_and_the_packages():
    env = host_env()
    assert Path(env["LD_PRELOAD"].split()[0]) == libpython()
    assert libpython().name.startswith("libpython3")
    import numpy
    import scipy

    paths = env["PYTHONPATH"].split(os.pathsep)
    for module in (numpy, scipy):
        assert str(Path(module.__file__).resolve().parent.parent) in paths
    p = subprocess.run(
        ["sh", "-c", f'eval "$({sys.executable} -m glider_cosim.hostenv)"; echo "$LD_PRELOAD"'],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert p.returncode == 0 and p.stdout.strip() == env["LD_PRELOAD"]


def test_c_host_runs_the_plant_like_our_master(host, plant, fmu_dir):
    folder, args = plant
    env = {k: v for k, v in os.environ.items() if k not in HOST_VARS} | host_env()
    p = subprocess.run([str(host), str(folder), *args], env=env, capture_output=True,
                       text=True, timeout=120)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    theta_g_c = float(p.stdout.strip())
    theta_g_ours = master_theta_g(fmu_dir / "GliderPlant.fmu")
    assert abs(theta_g_c - theta_g_ours) < 1e-9
    assert -0.5 < theta_g_c < -0.3  # near the steady glide (-0.394 rad) after 60 s


def test_c_host_without_host_env_cannot_load_the_fmu(host, plant):
    folder, args = plant
    env = {k: v for k, v in os.environ.items() if k not in HOST_VARS}
    p = subprocess.run([str(host), str(folder), *args], env=env, capture_output=True,
                       text=True, timeout=120)  # fmt: skip
    assert p.returncode == 3, p.stderr  # dlopen failed
    assert "undefined symbol" in p.stderr and "_Py" in p.stderr
