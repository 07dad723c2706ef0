"""Scenario runs of the three glider FMUs under the master, the CLI and failures."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from glider_controller.laws import passivity_law
from glider_cosim.runner import simulate
from glider_cosim.scenarios.scenario import load_scenario, parse_scenario
from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

pytestmark = pytest.mark.integration
E = equilibrium(GliderParams())
CONTRACT_COLUMNS = [
    "time", "plant.theta_meas", "plant.theta", "plant.V", "plant.theta_g", "plant.alpha",
    "plant.omega2", "plant.delta", "plant.x", "plant.z", "observer.theta_filt",
    "observer.V_hat", "observer.theta_g_hat", "observer.alpha_hat", "observer.omega2_hat",
    "observer.theta_hat", "controller.delta_cmd",
]  # fmt: skip


@pytest.fixture(scope="module")
def default_run(fmu_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("default")
    return simulate(None, out, fmu_dir=fmu_dir, build=False), out


def test_default_run_writes_the_contract(default_run):
    r, out = default_run
    assert r.status == "ok"
    assert r.columns == CONTRACT_COLUMNS
    assert r.data.shape == (3001, len(CONTRACT_COLUMNS))
    np.testing.assert_allclose(r.data[:, 0], np.arange(3001) * 0.02, rtol=0, atol=1e-12)
    with open(out / "results.csv") as f:
        assert f.readline().strip().split(",") == CONTRACT_COLUMNS
    m = json.loads((out / "metrics.json").read_text())
    for key in (
        "settling_time_s",
        "overshoot_rad",
        "rise_time_s",
        "control_effort",
        "max_abs_delta_cmd_rad",
        "scenario",
    ):
        assert key in m
    for png in ("glide_angle", "pitch", "tail_angle", "speed", "depth"):
        assert (out / f"{png}.png").stat().st_size > 10_000


def test_default_run_reference_result(default_run):
    """Reference figures of the default scenario (K_c = 10, observer, 50 Hz)."""
    r, _ = default_run
    m = r.metrics
    assert abs(r.column("plant.theta_g")[-1] - E.theta_g) < math.radians(0.01)
    assert m["settling_time_s"] == pytest.approx(11.18, abs=0.1)
    assert m["rise_time_s"] == pytest.approx(1.42, abs=0.05)
    assert math.degrees(m["overshoot_rad"]) == pytest.approx(5.43, abs=0.1)
    assert math.degrees(m["max_abs_delta_cmd_rad"]) == pytest.approx(3.85, abs=0.05)


def test_gauss_seidel_actuates_on_the_estimate_of_the_same_point(default_run):
    r, _ = default_run
    V, th, d = (
        r.column(c) for c in ("observer.V_hat", "observer.theta_g_hat", "controller.delta_cmd")
    )
    p = GliderParams()
    law = [passivity_law(v, t, 10.0, p, E, math.pi / 2) for v, t in zip(V, th)]
    np.testing.assert_allclose(d, law, rtol=0, atol=1e-14)


def test_jacobi_actuates_one_sample_later(fmu_dir):
    r = simulate(None, None, fmu_dir=fmu_dir, build=False, coupling="jacobi", stop_time=5.0)
    V, th, d = (
        r.column(c) for c in ("observer.V_hat", "observer.theta_g_hat", "controller.delta_cmd")
    )
    p = GliderParams()
    law = [passivity_law(v, t, 10.0, p, E, math.pi / 2) for v, t in zip(V, th)]
    np.testing.assert_allclose(d[1:], law[:-1], rtol=0, atol=1e-14)
    assert r.metrics["coupling"] == "jacobi"


NOISY = """
name = "noisy"
stop_time = 4.0
[plant]
noise_std = 0.02
noise_seed = {seed}
"""


def test_identical_seeds_give_identical_results(fmu_dir):
    runs = [
        simulate(
            parse_scenario(__import__("tomllib").loads(NOISY.format(seed=s))),
            None,
            fmu_dir=fmu_dir,
            build=False,
        )
        for s in (11, 11, 12)
    ]
    assert np.array_equal(runs[0].data, runs[1].data)
    assert not np.array_equal(runs[0].data, runs[2].data)
    meas = runs[0].column("plant.theta_meas") - runs[0].column("plant.theta")
    assert np.std(meas) == pytest.approx(0.02, rel=0.15)


def test_depth_event_hands_over_to_the_controller(fmu_dir):
    r = simulate("sec53-protocol", None, fmu_dir=fmu_dir, build=False, stop_time=40.0)
    z, d, t = r.column("plant.z"), r.column("controller.delta_cmd"), r.column("time")
    k = int(np.argmax(z >= 1.0))  # first point at or below 1 m
    assert k > 0
    assert np.all(d[:k] == pytest.approx(math.radians(2.0)))
    assert d[k] != pytest.approx(math.radians(2.0))
    assert r.metrics["t_on_s"] == pytest.approx(t[k])
    assert r.status == "ok"


def test_disturbance_pulse_changes_the_trajectory_only_after_it_starts(fmu_dir):
    base = load_scenario(None)
    base.stop_time = 12.0
    pulsed = load_scenario(None)
    pulsed.stop_time = 12.0
    from glider_cosim.master import Disturbance

    pulsed.disturbances = [Disturbance("plant.M_y", "pulse", 5.0, 0.02, 1.0)]
    a = simulate(base, None, fmu_dir=fmu_dir, build=False).column("plant.theta")
    b = simulate(pulsed, None, fmu_dir=fmu_dir, build=False).column("plant.theta")
    k = round(5.0 / 0.02)
    assert np.array_equal(a[: k + 1], b[: k + 1])
    assert abs(a[k + 25] - b[k + 25]) > 1e-3


def cli(*args, cwd=None):
    env = dict(os.environ)
    return subprocess.run(
        [sys.executable, "-c", "from glider_cosim.cli import console_main; console_main()", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
        timeout=300,
    )


def test_stall_stops_cleanly_and_keeps_the_rows(fmu_dir, tmp_path):
    p = cli("run", "sec53-literal", "--out", str(tmp_path), "--fmu-dir", str(fmu_dir), "--no-plots")
    assert p.returncode == 1
    err = p.stderr.strip().splitlines()
    assert len(err) == 1
    # the tumbling glider stalls: the observer's estimate (9.8 s) before the plant (11.1 s)
    assert "observer: fmi2DoStep at t = 9.8 s returned fmi2Discard" in err[0]
    assert "glider stalled: V = " in err[0]
    rows = (tmp_path / "results.csv").read_text().splitlines()
    assert len(rows) == 1 + 491  # header + t = 0 .. 9.8 s
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["status"] == "stopped" and m["end_time_s"] == pytest.approx(9.8)
    assert m["rise_time_s"] is None  # the controller never took over


def test_fmu_error_is_reported_with_instance_call_and_time(fmu_dir, tmp_path):
    # given under [fmus], the controller is not checked against our parameter table
    # before the run (that would exit 2): the FMU itself refuses K_c at initialisation,
    # when the master gets its command in Initialization Mode
    sc = tmp_path / "bad.toml"
    controller = fmu_dir / "GliderController.fmu"
    sc.write_text(f"[fmus]\ncontroller = '{controller}'\n[controller]\nK_c = -1.0\n")
    p = cli("run", str(sc), "--out", str(tmp_path / "o"), "--fmu-dir", str(fmu_dir))
    assert p.returncode == 1
    assert p.stderr.count("\n") == 1
    assert (
        "controller: fmi2GetReal(delta_cmd) in Initialization Mode at t = 0 s returned "
        "fmi2Error: "
        "[fmi2Error] K_c = -1.0 is invalid: expected a finite value in (0, inf)"
    ) in p.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "nope.toml"], "nope.toml: scenario file does not exist"),
        (["run", "--step", "-1"], "argument --step: '-1' is invalid"),
        (["run", "--coupling", "x"], "argument --coupling: invalid choice"),
        (["frobnicate"], "invalid choice: 'frobnicate'"),
    ],
)
def test_cli_bad_input_exits_2_with_one_line(args, message, tmp_path):
    p = cli(*args, cwd=tmp_path)
    assert p.returncode == 2
    assert message in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1
    assert "Traceback" not in p.stderr


def test_cli_run_repeatedly_exits_0(fmu_dir, tmp_path):
    """The process never aborts at exit (pythonfmu's finalizer), CLI and API alike."""
    for i in range(5):
        p = cli(
            "run",
            "--stop-time",
            "1",
            "--out",
            str(tmp_path / str(i)),
            "--fmu-dir",
            str(fmu_dir),
            "--no-plots",
        )
        assert p.returncode == 0, p.stderr
    script = (
        "from glider_cosim.runner import simulate; "
        f"r = simulate(None, None, fmu_dir={str(fmu_dir)!r}, build=False, stop_time=1.0);"
        "assert r.status == 'ok'"
    )
    for _ in range(5):
        p = subprocess.run([sys.executable, "-c", script], capture_output=True, timeout=300)
        assert p.returncode == 0, p.stderr


def test_analyze_json_is_one_object_on_stdout():
    p = cli("analyze", "--json")
    assert p.returncode == 0, p.stderr
    lines = p.stdout.strip().splitlines()
    assert len(lines) == 1
    data = json.loads(lines[0])
    assert set(data["equilibrium"]) >= {"V", "theta_g", "alpha", "omega2"}
    assert data["stable_K_c"]["continuous"][1] is None
    assert data["stable_K_c"]["sampled"][0] > data["stable_K_c"]["continuous"][0]
