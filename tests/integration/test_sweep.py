"""Sweeps on a local Dask cluster of 2 worker processes: failures, resume, a killed worker."""

from __future__ import annotations

import contextlib
import csv
import os
import re
import signal
import socket
import threading
import time
import warnings

import pytest

from glider_cosim.cli import main as cli_main
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.sweeps.cluster import SweepClusterError, check_workers, package_version
from glider_cosim.sweeps.sweep import (
    expand,
    make_client,
    parse_param,
    run_many,
    run_sweep,
    write_plots,
)

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


@pytest.mark.parametrize(
    ("param", "message"),
    [
        ("controller.K_c=-1,5", "glider-cosim sweep: error: --param 'controller.K_c=-1,5': -1 is "
         "invalid: expected a finite value in (0, inf)"),
        ("controller.K_c=6 deg,8", "glider-cosim sweep: error: --param 'controller.K_c=6 deg,8': "
         "'6 deg' is invalid: K_c has no unit: expected a plain number"),
    ],
)  # fmt: skip
def test_bad_values_are_refused_before_any_run(fmu_dir, tmp_path, capsys, param, message):
    """Every --param value is checked like --set: exit 2, one line, no run (issue 28)."""
    out = tmp_path / "out"
    code = cli_main(["sweep", "--param", param, "--fmu-dir", str(fmu_dir), "--out", str(out)])
    captured = capsys.readouterr()
    assert (code, captured.err, captured.out) == (2, message + "\n", "")
    assert not out.exists()


def test_workers_are_checked_for_the_clients_version(client):
    mine = package_version()
    assert mine and set(check_workers(client).values()) == {mine}
    with pytest.raises(SweepClusterError, match=rf"^worker tcp://\S+ has glider-cosim {mine}, "
                       r"the client glider-cosim 9\.9\.9 \(and 1 more worker\(s\)\): install "
                       r"glider-cosim 9\.9\.9 on every worker$"):  # fmt: skip
        check_workers(client, version="9.9.9")
    with pytest.raises(SweepClusterError, match=r"^worker tcp://\S+ has no glider-cosim-absent "
                       r"installed, the client glider-cosim-absent 1\.0"):  # fmt: skip
        check_workers(client, version="1.0", dist="glider-cosim-absent")


def test_a_worker_that_joined_with_another_version_refuses_its_tasks(client):
    """Workers joining after the check at connect are checked by every task."""
    sc = load_scenario(None)
    fut = client.submit(run_many, sc, [], {}, None, False, "9.9.9", pure=False)
    with pytest.raises(SweepClusterError, match=r"has glider-cosim \S+, the client glider-cosim "
                       r"9\.9\.9"):  # fmt: skip
        fut.result()


def test_no_dashboard_and_no_port_warning_unless_asked(fmu_dir, tmp_path, capfd):
    with socket.socket() as s:
        with contextlib.suppress(OSError):  # else another cluster holds it: the same case
            s.bind(("", 8787))
            s.listen()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            c = make_client(1)
            try:
                assert c.cluster.scheduler.http_server.port != 8787
                app = c.cluster.scheduler.http_application
                rules = app.default_router.rules + app.wildcard_router.rules
                routes = {getattr(r.matcher, "regex", re.compile("")).pattern for r in rules}
                assert "/health$" in routes and "/status$" not in routes  # no dashboard
            finally:
                c.close()
                c.cluster.close()
        assert not [w for w in caught if "already in use" in str(w.message)]
        code = cli_main(["sweep", "--param", "controller.K_c=10", "--stop-time", "1",
                         "--workers", "1", "--fmu-dir", str(fmu_dir), "--out", str(tmp_path),
                         "--no-plots", "--dashboard"])  # fmt: skip
    out, err = capfd.readouterr()
    assert code == 0
    assert re.search(r"^sweep: Dask dashboard at http://\S+:\d+/status$", out, re.M), out
    assert "already in use" not in err


def test_sweeps_back_to_back_on_one_client(client, fmu_dir, tmp_path):
    """Each sweep scatters the FMUs again; the previous sweep's copies being released
    at the same moment must not take the new ones with them (seen as 'lost
    dependencies' about 1 sweep in 15 when the key was the same)."""
    sc = load_scenario(None)
    runs = expand([parse_param("controller.K_c=9:11:4")], sc, fmu_dir, stop_time=0.1)
    for i in range(15):
        res = run_sweep(sc, runs, tmp_path / f"s{i}", client, fmu_dir, stop_time=0.1, chunk=1)
        assert res.failed == 0, rows(res.path)[0]["message"]


def test_the_scheduler_is_checked_too(client, monkeypatch):
    """The local cluster's scheduler runs in this process: give it another version."""
    import importlib.metadata

    mine = package_version()
    real = importlib.metadata.distribution

    class Old:
        version = "0.0.1"

    # version() looks distribution() up at call time; the workers (other processes) and
    # the function sent to them (importlib.metadata.version, by reference) are unchanged
    monkeypatch.setattr(importlib.metadata, "distribution",
                        lambda d: Old() if d == "glider-cosim" else real(d))  # fmt: skip
    with pytest.raises(SweepClusterError, match=r"^scheduler tcp://\S+ has glider-cosim 0\.0\.1, "
                       rf"the client glider-cosim {mine}: the scheduler unpickles"):  # fmt: skip
        check_workers(client, version=mine)


def test_the_exit_code_after_a_resume_counts_earlier_failures(fmu_dir, tmp_path, capsys):
    # K_c = 0.05: the observer's estimate stalls at 2.58 s (a run that fails, not a bad value)
    args = ["sweep", "--param", "controller.K_c=10,0.05", "--stop-time", "3", "--workers", "1",
            "--fmu-dir", str(fmu_dir), "--out", str(tmp_path), "--no-plots"]  # fmt: skip
    assert cli_main(args) == 1
    out = capsys.readouterr().out
    assert "2 run now, 1 failed" in out
    # the console names the failed run and why (issue 28)
    assert re.search(r"^  failed: controller.K_c=0.05: stopped: observer: fmi2DoStep at "
                     r"t = 2.58 s returned fmi2Discard: .*stalled", out, re.M), out  # fmt: skip
    # the last line: how many settled (none in 3 s), and which values did not, and how
    assert re.fullmatch(r"sweep: 0 of 2 runs settled; not settled: controller.K_c=10 "
                        r"\([a-z ]+\), controller.K_c=0.05 \(stopped\)",
                        out.splitlines()[-1]), out  # fmt: skip
    assert cli_main(args) == 1  # nothing run now, the failure is in sweep.csv
    assert "(2 already done), 0 run now, 0 failed, 0.00 runs/s; 1 of 2 failed overall" in (
        capsys.readouterr().out
    )


# ------------------------------------------------------------- bit for bit, reuse
#: sweep points of the default scenario: settled, a limit cycle with noise, a run the
#: observer stops (K_c = 0.05 stalls at 2.58 s), one the controller refuses (K_c = -1),
#: and one that sets a parameter the others leave at the FMU's default (noise_std)
POINTS = {
    "A": ({"controller.K_c": 10.0}, None),
    "B": ({"controller.K_c": 4.0, "plant.noise_std": 0.01}, 3),
    "C": ({"controller.K_c": 0.05}, None),
    "D": ({"controller.K_c": -1.0}, None),
}


def _separate(fmu_dir, name, out=None):
    """The point as a separate ``simulate`` run (a fresh co-simulation)."""
    from glider_cosim.runner import simulate
    from glider_cosim.scenarios.overrides import apply_overrides

    params, seed = POINTS[name]
    over = dict(params, **({"plant.noise_seed": seed} if seed is not None else {}))
    return simulate(apply_overrides(load_scenario(None), over), out, fmu_dir=fmu_dir,
                    build=False, plots=False)  # fmt: skip


def _same(a, b) -> bool:
    """Equal, bit for bit for floats (NaN too), None only for None."""
    import struct

    if isinstance(a, float) and isinstance(b, float):
        return struct.pack("<d", a) == struct.pack("<d", b)
    return type(a) is type(b) and a == b


def _task(fmu_dir, order, trajectories=False):
    """The points in ``order`` as one worker task runs them (one co-simulation, reset
    between runs), in this process."""
    from glider_cosim.scenarios.system import system_for
    from glider_cosim.sweeps.worker import _SIMS

    _SIMS.clear()
    sc = load_scenario(None)
    fmus = {k: str(v) for k, v in system_for(sc, fmu_dir).fmus.items()}
    runs = [{"run_id": f"{i}{n}", "params": POINTS[n][0], "seed": POINTS[n][1]}
            for i, n in enumerate(order)]  # fmt: skip
    return run_many(sc, runs, fmus, trajectories=trajectories)


def _mismatches(fmu_dir, order, rows_) -> list[str]:
    import numpy as np

    from glider_cosim.runner.outcome import wrap_angle
    from glider_cosim.sweeps.worker import METRIC_KEYS

    bad = []
    for name, row in zip(order, rows_, strict=True):
        ref = _separate(fmu_dir, name)
        if (row["status"], row["message"]) != (ref.status, ref.message):
            bad.append(f"{name}: status {row['status']!r} != {ref.status!r}")
            continue
        if ref.status == "error":  # refused at initialisation: no rows, no metrics
            assert len(ref.data) == 0 and "settling_time_s" not in row
            continue
        want = dict(ref.metrics)
        err = wrap_angle(ref.column("observer.theta_g_hat") - ref.column("plant.theta_g"))
        want["estimation_rms_rad"] = float(np.sqrt(np.mean(err**2)))
        bad += [f"{name}: {k} {row[k]!r} != {want.get(k)!r}"
                for k in METRIC_KEYS if not _same(row[k], want.get(k))]  # fmt: skip
    return bad


ORDER = ("A", "B", "C", "A", "D", "B", "A", "C")


@pytest.mark.parametrize("flavor", ["native", "python"])
def test_a_tasks_runs_are_bit_for_bit_separate_runs(flavor, fmu_dir, native_dir):
    """A, B, A, ... in one task (one co-simulation reset between runs, a stopped run's
    too; a refused one replaces it): every row's status, message and metrics are those of
    a separate run of the point, bit for bit."""
    folder = native_dir if flavor == "native" else fmu_dir
    rows_ = _task(folder, ORDER)
    assert [r["status"] for r in rows_] == ["ok", "ok", "stopped", "ok", "error", "ok", "ok",
                                            "stopped"]  # fmt: skip
    assert rows_[0]["outcome"] == "settled" and rows_[1]["outcome"] != "settled"
    assert _mismatches(folder, ORDER, rows_) == []


def test_a_stopped_run_leaves_its_co_simulation_to_be_reset_and_an_error_does_not(
    native_dir, monkeypatch
):
    from glider_cosim.sweeps import worker

    made = []
    real = worker._new_sim
    monkeypatch.setattr(worker, "_new_sim", lambda *a: made.append(real(*a)) or made[-1])
    order = ("C", "A", "D", "A")  # stopped, ok (reset), error (replaced), ok (new)
    rows_ = _task(native_dir, order)
    assert [r["status"] for r in rows_] == ["stopped", "ok", "error", "ok"]
    assert len(made) == 2 and not made[0].instances["plant"].alive  # closed after D
    assert _mismatches(native_dir, order, rows_) == []


def test_the_reuse_check_sees_a_leaking_reset(native_dir, monkeypatch):
    """The check above fails when a reset keeps the previous run's parameters."""
    from glider_cosim.master.cosimulation import CoSimulation

    real = CoSimulation.reset
    monkeypatch.setattr(CoSimulation, "reset", lambda self, p=None, replace=False:
                        real(self, p, replace=False))  # fmt: skip
    order = ("B", "A")
    bad = _mismatches(native_dir, order, _task(native_dir, order))
    assert bad and all(b.startswith("A: ") for b in bad), bad


def test_a_tasks_trajectories_are_the_bytes_of_separate_runs(native_dir, tmp_path):
    order = ("A", "C", "B", "A")
    rows_ = _task(native_dir, order, trajectories=True)
    for i, (name, row) in enumerate(zip(order, rows_, strict=True)):
        ref = _separate(native_dir, name, tmp_path / f"{i}{name}")
        assert row["trajectory"] == ref.files["results"].read_bytes(), name


def test_sweep_csv_holds_the_metrics_of_separate_runs(client, native_dir, tmp_path):
    """The metrics in sweep.csv (the text read back) are the separate runs' values."""
    from glider_cosim.sweeps.worker import METRIC_KEYS

    sc = load_scenario(None)
    order = ("A", "B", "C", "A")
    runs = [{"run_id": f"{i}{n}", "params": POINTS[n][0], "seed": POINTS[n][1]}
            for i, n in enumerate(order)]  # fmt: skip
    run_sweep(sc, runs, tmp_path, client, native_dir, chunk=2)
    table = {r["run_id"]: r for r in rows(tmp_path / "sweep.csv")}
    read = []
    for r in runs:
        row = dict(table[r["run_id"]])
        for k in METRIC_KEYS:
            row[k] = None if row[k] == "" else (row[k] if k == "outcome" else float(row[k]))
        read.append(row)
    assert _mismatches(native_dir, order, read) == []


_TRIM = """
import os
from glider_cosim.sweeps.cluster import make_client
client = make_client(1)
try:
    print(sorted(client.run(lambda: os.environ.get("MALLOC_TRIM_THRESHOLD_")).values()))
finally:
    client.close()
    client.cluster.close()
"""


def test_local_workers_start_without_dasks_malloc_trim():
    """Dask starts its workers with MALLOC_TRIM_THRESHOLD_=65536 (13-20 % more CPU a run
    here); ours start without it, and a value the user set still reaches them. A fresh
    interpreter each: Dask writes the variable into the environment of the process that
    starts the workers."""
    import subprocess
    import sys

    def workers_see(extra: dict) -> str:
        env = {k: v for k, v in os.environ.items() if k != "MALLOC_TRIM_THRESHOLD_"}
        done = subprocess.run([sys.executable, "-c", _TRIM], env={**env, **extra}, text=True,
                              capture_output=True, check=True, timeout=180)  # fmt: skip
        return done.stdout.strip().splitlines()[-1]

    assert workers_see({}) == "[None]"
    assert workers_see({"MALLOC_TRIM_THRESHOLD_": "262144"}) == "['262144']"


@pytest.mark.parametrize("flavor", ["native", "python"])
def test_each_failed_runs_message_is_its_own(flavor, fmu_dir, native_dir):
    """K_c = 2 stalls the observer at a time that depends on V_0 (2.48, 9.08, 5.1, 10.4 s):
    in one task (one co-simulation, reset between runs) each row's message names its own
    run's time, in the master's words and in the FMU's, and is the message of a separate
    run of the point (a reset used to keep the log, and the message was the first run's)."""
    from glider_cosim.runner import simulate
    from glider_cosim.scenarios.overrides import apply_overrides
    from glider_cosim.scenarios.system import system_for
    from glider_cosim.sweeps.worker import _SIMS

    folder = native_dir if flavor == "native" else fmu_dir
    _SIMS.clear()
    sc = load_scenario(None)
    fmus = {k: str(v) for k, v in system_for(sc, folder).fmus.items()}
    points = [{"controller.K_c": 2.0, "plant.V_0": v} for v in (0.1, 0.2, 0.3, 0.4)]
    runs = [{"run_id": f"v{i}", "params": p, "seed": None} for i, p in enumerate(points)]
    rows_ = run_many(sc, runs, fmus, stop_time=12.0)
    assert [r["status"] for r in rows_] == ["stopped"] * 4
    times = []
    for row, point in zip(rows_, points, strict=True):
        said = re.findall(r"at t = ([0-9.]+) s", row["message"])
        assert len(said) == 2 and said[0] == said[1], row["message"]
        assert float(said[0]) == pytest.approx(row["end_time_s"], abs=1e-9), row["message"]
        times.append(said[0])
        ref = simulate(apply_overrides(load_scenario(None), point), None, fmu_dir=folder,
                       build=False, plots=False, stop_time=12.0)  # fmt: skip
        assert (row["status"], row["message"]) == (ref.status, ref.message)
    assert len(set(times)) == 4, times  # four different times: four different messages


def test_a_sweep_into_another_sweeps_folder_is_refused(native_dir, tmp_path, capsys):
    """Issue 45: a second sweep with another --param into the same --out was appended to
    the first one's sweep.csv. Now: one line, exit 2, nothing written; the same sweep
    resumes; --restart replaces it."""
    common = ["--stop-time", "1", "--workers", "1", "--fmu-dir", str(native_dir),
              "--out", str(tmp_path), "--no-plots"]  # fmt: skip
    assert cli_main(["sweep", "--param", "controller.K_c=8,10", *common]) == 0
    before = (tmp_path / "sweep.csv").read_bytes()
    capsys.readouterr()
    assert cli_main(["sweep", "--param", "plant.V_0=0.2,0.3", *common]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err == (
        f"glider-cosim sweep: error: {tmp_path} holds the results of another sweep (--param "
        "controller.K_c=8,10 --stop-time 1, 2 runs), not of this one (--param "
        "plant.V_0=0.2,0.3 --stop-time 1, 2 runs): give another --out, remove "
        f"{tmp_path}, or pass --restart to replace them\n"
    )
    assert (tmp_path / "sweep.csv").read_bytes() == before
    assert cli_main(["sweep", "--param", "controller.K_c=8,10", *common]) == 0
    assert "2 runs (2 already done), 0 run now" in capsys.readouterr().out
    assert cli_main(["sweep", "--param", "plant.V_0=0.2,0.3", "--restart", *common]) == 0
    assert [r["plant.V_0"] for r in rows(tmp_path / "sweep.csv")] in (
        ["0.2", "0.3"], ["0.3", "0.2"])  # fmt: skip
