"""Sweeps on a local Dask cluster of 2 worker processes: failures, resume, a killed worker."""

from __future__ import annotations

import csv
import os
import re
import signal
import threading
import time

import pytest

from glider_cosim.cli import main as cli_main
from glider_cosim.scenario import load_scenario
from glider_cosim.sweep import expand, make_client, parse_param, run_sweep, write_plots

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def client():
    c = make_client(workers=2)
    yield c
    c.close()
    c.cluster.close()


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_sweep_records_failures_and_resumes(client, fmu_dir, tmp_path):
    sc = load_scenario(None)
    specs = [parse_param("controller.K_c=10,20,-1"), parse_param("plant.K_L=uniform(-5%,5%)")]
    runs = expand(specs, sc, fmu_dir, samples=2, rng_seed=3, stop_time=5.0)
    assert len(runs) == 6
    res = run_sweep(sc, runs, tmp_path, client, fmu_dir, stop_time=5.0)
    assert (res.total, res.done, res.skipped, res.failed, res.failed_total) == (6, 6, 0, 2, 2)
    table = rows(tmp_path / "sweep.csv")
    assert sorted(r["run_id"] for r in table) == sorted(r["run_id"] for r in runs)
    bad = [r for r in table if r["controller.K_c"] == "-1.0"]
    assert len(bad) == 2 and all(r["status"] == "error" for r in bad)
    assert all("K_c = -1.0 is invalid" in r["message"] for r in bad)
    good = [r for r in table if r["status"] == "ok"]
    assert len(good) == 4 and all(float(r["control_effort"]) > 0 for r in good)
    # the same sweep again: nothing to redo
    again = run_sweep(sc, runs, tmp_path, client, fmu_dir, stop_time=5.0)
    assert (again.done, again.skipped, again.failed, again.failed_total) == (0, 6, 0, 2)
    assert len(rows(tmp_path / "sweep.csv")) == 6
    assert [p.name for p in write_plots(tmp_path / "sweep.csv", tmp_path)] == [
        "settling_vs_effort.png",
        "stability_boundary.png",
    ]


def test_results_do_not_depend_on_worker_reuse(client, fmu_dir, tmp_path):
    """A reset instance gives the same metrics as a fresh one."""
    sc = load_scenario(None)
    runs = expand([parse_param("controller.K_c=12,12,12,12")], sc, fmu_dir, stop_time=5.0)
    # identical parameters: identical ids, so give each its own seed (noise is off)
    for i, r in enumerate(runs):
        r["seed"] = i
        r["run_id"] = f"reuse{i}"
    run_sweep(sc, runs, tmp_path, client, fmu_dir, stop_time=5.0)
    efforts = {r["control_effort"] for r in rows(tmp_path / "sweep.csv")}
    assert len(efforts) == 1


def test_a_killed_worker_has_its_runs_retried(client, fmu_dir, tmp_path):
    sc = load_scenario(None)
    runs = expand([parse_param("controller.K_c=8:30:16")], sc, fmu_dir, stop_time=20.0)
    pids = client.run(os.getpid)
    result = {}

    def sweep():
        result["r"] = run_sweep(sc, runs, tmp_path, client, fmu_dir, stop_time=20.0)

    t = threading.Thread(target=sweep)
    t.start()
    deadline = time.time() + 60
    while time.time() < deadline:
        if (tmp_path / "sweep.csv").exists() and len(rows(tmp_path / "sweep.csv")) >= 2:
            break
        time.sleep(0.05)
    os.kill(next(iter(pids.values())), signal.SIGKILL)
    t.join(timeout=180)
    assert not t.is_alive()
    table = rows(tmp_path / "sweep.csv")
    assert sorted(r["run_id"] for r in table) == sorted(r["run_id"] for r in runs)
    assert all(r["status"] == "ok" for r in table)
    assert result["r"].failed == 0
    client.wait_for_workers(2, timeout=60)  # the nanny restarted it


@pytest.mark.parametrize(
    ("param", "message"),
    [
        ("controller.K_x=1,2", r"--param controller.K_x: instance controller \(GliderController\) "
         r"has no variable 'K_x'"),
        ("plant.theta_g=1,2", r"--param plant.theta_g: plant.theta_g has causality output: "
         r"expected one of parameter, input"),
    ],
)  # fmt: skip
def test_unknown_targets_are_refused_before_any_work(fmu_dir, tmp_path, capsys, param, message):
    out = tmp_path / "out"
    code = cli_main(["sweep", "--param", param, "--fmu-dir", str(fmu_dir), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and re.search(message, err), err
    assert not out.exists()  # nothing was sent, nothing written
