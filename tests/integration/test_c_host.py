"""A C host without Python runs our three FMUs as a closed loop, with no setup at all.

tests/integration/c_host/host.c is compiled here with gcc against the FMI 2.0 headers
fmpy ships. It reads a plan (FMUs, parameters, connections, recorded outputs), dlopens
the FMUs' binaries and steps them with Jacobi coupling, printing every communication
point. Run under ``env -i PATH=/usr/bin:/bin`` (Debian's ``/usr/bin/python3`` first on
PATH, no LD_PRELOAD, PYTHONPATH or PYTHONHOME), the FMUs' runtime loads and starts the
Python recorded at build time; the result must equal our master's Jacobi run bit for bit.
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from c_host_helpers import (
    GCC_FLAGS,
    HEADERS,
    RECORD,
    STOP,
    compile_host,
    master_jacobi_run,
    write_plan,
)
from system_tools import require_tool

from glider_cosim.interop.hostenv import host_env, libpython
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for

pytestmark = pytest.mark.integration
EMPTY_ENV = {"PATH": "/usr/bin:/bin"}


@pytest.fixture(scope="module")
def host(tmp_path_factory) -> Path:
    gcc = require_tool("gcc")
    assert (HEADERS / "fmi2Functions.h").is_file()
    return compile_host(gcc, tmp_path_factory.mktemp("c_host") / "host", GCC_FLAGS)


@pytest.fixture(scope="module")
def loop(fmu_dir, tmp_path_factory):
    """The default scenario's system, its FMUs unzipped, and a plan for the C host."""
    sc = load_scenario("default")
    system = system_for(sc, fmu_dir)
    plan = write_plan(system, tmp_path_factory.mktemp("loop"), step=sc.step)
    return system, plan


def master_jacobi(system) -> np.ndarray:
    rec = master_jacobi_run(system)
    assert rec.columns == ["time", *RECORD]
    return rec.array()


def run_host(host: Path, plan: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run([str(host), str(plan)], env=env, capture_output=True, text=True,
                          timeout=180)  # fmt: skip


def test_c_host_in_an_empty_environment_equals_our_master_bit_for_bit(host, loop):
    system, plan = loop
    p = run_host(host, plan, EMPTY_ENV)
    assert p.returncode == 0, p.stderr[-3000:]
    c_rows = np.array([[float(x) for x in line.split(",")] for line in p.stdout.splitlines()])
    ours = master_jacobi(system)
    assert c_rows.shape == ours.shape == (round(STOP / 0.02) + 1, 1 + len(RECORD))
    assert np.array_equal(c_rows, ours)  # bit for bit
    # it really is the closed loop: the glide angle moves from -35 deg towards -22.6 deg
    assert c_rows[0, 1] == pytest.approx(np.radians(-35.0))
    assert np.radians(-30.0) < c_rows[-1, 1] < np.radians(-18.0)


def test_c_host_stepping_from_threads_equals_our_master(host, loop, tmp_path):
    """Each doStep from a new thread, the runtime having started Python on the main one."""
    system, plan = loop
    threaded = tmp_path / "plan.txt"
    threaded.write_text(plan.read_text() + "threads\n")
    p = run_host(host, threaded, EMPTY_ENV)
    assert p.returncode == 0, p.stderr[-3000:]
    c_rows = np.array([[float(x) for x in line.split(",")] for line in p.stdout.splitlines()])
    assert np.array_equal(c_rows, master_jacobi(system))


def test_c_host_with_another_python_configuration_gets_one_line_not_a_crash(host, loop, tmp_path):
    _, plan = loop
    bad = tmp_path / "py.cfg"
    bad.write_text("libpython=/nonexistent/libpython3.11.so\nhome=/nonexistent\n")
    p = run_host(host, plan, EMPTY_ENV | {"GLIDER_FMI_PYTHON_CONFIG": str(bad)})
    assert p.returncode == 4, p.stderr  # fmi2Instantiate returned NULL, no signal
    assert "status 4 logStatusFatal: plant: fmi2Instantiate: Python is not available: cannot " \
           "load /nonexistent/libpython3.11.so" in p.stderr  # fmt: skip
    assert "GLIDER_FMI_PYTHON_CONFIG" in p.stderr


def test_c_host_with_a_written_configuration_runs(host, loop, tmp_path):
    """What another machine does: write the configuration there and point at it."""
    _, plan = loop
    cfg = tmp_path / "py.cfg"
    out = subprocess.run([sys.executable, "-m", "glider_cosim.interop.hostenv", "--config"],
                         capture_output=True, text=True, timeout=60, check=True).stdout  # fmt: skip
    cfg.write_text(out)
    p = run_host(host, plan, EMPTY_ENV | {"GLIDER_FMI_PYTHON_CONFIG": str(cfg)})
    assert p.returncode == 0, p.stderr[-3000:]
    assert len(p.stdout.splitlines()) == round(STOP / 0.02) + 1


def host_env_under(path: str) -> dict[str, str]:
    """What ``glider-cosim host-env`` prints when PATH is ``path``."""
    p = subprocess.run([sys.executable, "-m", "glider_cosim.interop.hostenv"], env={"PATH": path},
                       capture_output=True, text=True, timeout=60, check=True)  # fmt: skip
    env = {}
    for line in p.stdout.splitlines():
        name, _, value = line.removeprefix("export ").partition("=")
        env[name] = shlex.split(value)[0]
    return env


def test_c_host_with_the_host_env_environment_runs(host, loop):
    """host-env's LD_PRELOAD/PYTHONPATH/PYTHONHOME: the runtime starts the preloaded Python."""
    _, plan = loop
    env = host_env_under(EMPTY_ENV["PATH"])
    assert set(env) >= {"LD_PRELOAD", "PYTHONPATH"}
    p = run_host(host, plan, EMPTY_ENV | env)
    assert p.returncode == 0, p.stderr[-3000:]
    assert len(p.stdout.splitlines()) == round(STOP / 0.02) + 1


def test_host_env_names_libpython_the_packages_and_pythonhome():
    env = host_env()
    assert Path(env["LD_PRELOAD"].split()[0]) == libpython()
    assert libpython().name.startswith("libpython3")
    import numpy
    import scipy

    paths = env["PYTHONPATH"].split(os.pathsep)
    for module in (numpy, scipy):
        assert str(Path(module.__file__).resolve().parent.parent) in paths
    p = subprocess.run(
        [
            "sh",
            "-c",
            f'eval "$({sys.executable} -m glider_cosim.interop.hostenv)"; echo "$LD_PRELOAD"',
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert p.returncode == 0 and p.stdout.strip() == env["LD_PRELOAD"]
    # with another python3 first on PATH, PYTHONHOME is needed and given
    first = shutil.which("python3", path=EMPTY_ENV["PATH"])
    other = first and Path(os.path.realpath(first)).parent.parent != Path(sys.base_prefix).resolve()
    assert host_env_under(EMPTY_ENV["PATH"]).get("PYTHONHOME") == (
        sys.base_prefix if other else None
    )
