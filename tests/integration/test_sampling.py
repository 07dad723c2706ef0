"""The communication step drives the observer's pre-filter (f_sample = 1/step)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from glider_cosim.runner import simulate
from glider_cosim.scenarios.overrides import apply_overrides
from glider_cosim.scenarios.sampling import SamplingMismatchWarning
from glider_cosim.scenarios.scenario import load_scenario

pytestmark = pytest.mark.integration


def cli(*args):
    code = "from glider_cosim.cli import console_main; console_main()"
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=300
    )


def _theta_g(fmu_dir, overrides, step):
    sc = apply_overrides(load_scenario(None), overrides)
    return simulate(sc, None, fmu_dir=fmu_dir, build=False, step=step, stop_time=20.0).column(
        "plant.theta_g"
    )


def test_the_observer_samples_at_the_communication_step(fmu_dir):
    auto = _theta_g(fmu_dir, {}, 0.01)
    np.testing.assert_array_equal(auto, _theta_g(fmu_dir, {"observer.f_sample": 100.0}, 0.01))
    with pytest.warns(SamplingMismatchWarning, match="f_sample = 50 Hz differs"):
        stale = _theta_g(fmu_dir, {"observer.f_sample": 50.0}, 0.01)
    assert np.max(np.abs(stale - auto)) > 1e-4


def test_cli_warns_in_one_line_and_refuses_a_too_long_step(fmu_dir, tmp_path):
    args = ("run", "--fmu-dir", str(fmu_dir), "--no-plots", "--stop-time", "1")
    p = cli(*args, "--out", str(tmp_path / "a"), "--step", "0.01", "--set", "observer.f_sample=50")
    assert p.returncode == 0
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("glider-cosim: warning: ")
    assert (
        "observer.f_sample = 50 Hz differs from the communication rate 1/step = 100 Hz" in lines[0]
    )
    p = cli(*args, "--out", str(tmp_path / "b"), "--step", "0.1")
    assert p.returncode == 2
    assert "expected observer.f_cutoff below 5 Hz" in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1
