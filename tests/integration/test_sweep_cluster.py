"""Sweeps on a cluster started the Dask way: ``dask scheduler`` and two ``dask worker``
processes, the workers in private mount namespaces where the client's FMU and output
folders and the checkout's ``fmus/`` are hidden under empty tmpfs mounts (as on other
machines). Faults with real processes: a worker SIGKILLed mid-sweep, a client SIGKILLed
mid-sweep and resumed. Needs root and ``unshare`` (CI runs as root)."""

from __future__ import annotations

import csv
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.sweeps.sweep import expand, parse_param, run_sweep

pytestmark = pytest.mark.integration
REPO = Path(__file__).resolve().parents[2]


def _no_namespaces() -> str:
    """Why the workers cannot get private mount namespaces here ('' if they can)."""
    if os.geteuid() != 0:
        return "needs root: the workers' private mount namespaces (unshare -m) and tmpfs"
    if shutil.which("unshare") is None:
        return "needs util-linux's unshare for the workers' private mount namespaces"
    probe = subprocess.run(
        ["unshare", "-m", "--propagation", "private", "sh", "-c", "mount -t tmpfs none /mnt"],
        capture_output=True,
        text=True,
    )
    if probe.returncode != 0:
        return f"unshare -m / mount tmpfs failed here: {probe.stderr.strip()}"
    return ""


def rows(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _group_alive(pgid: int) -> list[int]:
    """Processes of a process group that are not zombies."""
    alive = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        if int(fields[2]) == pgid and fields[0] != "Z":
            alive.append(int(d.name))
    return alive


class Cluster:
    """A scheduler and two namespaced workers, each in its own process group."""

    def __init__(self, base: Path, hidden: list[Path]):
        self.base, self.hidden, self.procs = base, hidden, []

    def start(self) -> None:
        sched_file = self.base / "scheduler.json"
        self._start("scheduler", [sys.executable, "-m", "distributed.cli.dask_scheduler",
                                  "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                  "--scheduler-file", str(sched_file)])  # fmt: skip
        deadline = time.time() + 30
        while not sched_file.exists() and time.time() < deadline:
            time.sleep(0.05)
        time.sleep(0.1)  # the file is written in one go, but give it a moment
        assert sched_file.exists(), (self.base / "scheduler.log").read_text()
        self.address = json.loads(sched_file.read_text())["address"]
        for i in range(2):
            self.start_worker(f"w{i}")

    def _start(self, name: str, cmd: list[str]) -> subprocess.Popen:
        log = open(self.base / f"{name}.log", "w")  # noqa: SIM115 - closed in stop()
        # each process's temporary files (the scheduler's dask-scratch-space: it is
        # SIGKILLed, so never removes it) stay in the test's own folder
        tmp = self.base / f"tmp-{name}"
        tmp.mkdir(exist_ok=True)
        env = {**os.environ, "TMPDIR": str(tmp)}
        p = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
                             cwd=self.base, env=env)  # fmt: skip
        p.log = log
        self.procs.append(p)
        return p

    def start_worker(self, name: str) -> None:
        """``dask worker`` in a private mount namespace: the client's folders are empty
        tmpfs mounts there; its scratch (and TMPDIR) is a tmpfs of its own."""
        scratch = self.base / f"scratch-{name}"
        scratch.mkdir()
        script = (
            'for d in "$@"; do mount -t tmpfs none "$d" || exit 97; done; '
            f'TMPDIR="{scratch}" exec "{sys.executable}" -m distributed.cli.dask_worker '
            f"{self.address} --name {name} --nworkers 1 --nthreads 1 --no-dashboard "
            f'--local-directory "{scratch}"'
        )
        dirs = [str(d) for d in [*self.hidden, scratch]]
        self._start(name, ["unshare", "-m", "--propagation", "private", "sh", "-c", script,
                           "sh", *dirs])  # fmt: skip

    def stop(self) -> list[int]:
        """SIGKILL every process group; returns the processes still alive after 10 s."""
        for p in self.procs:
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        left: list[int] = []
        for p in self.procs:
            p.wait(timeout=10)
            p.log.close()
        deadline = time.time() + 10
        while time.time() < deadline:
            left = [pid for p in self.procs for pid in _group_alive(p.pid)]
            if not left:
                break
            time.sleep(0.1)
        return left


@pytest.fixture(scope="module")
def cluster(tmp_path_factory, fmu_dir):
    reason = _no_namespaces()
    if reason:
        pytest.skip(reason)
    base = tmp_path_factory.mktemp("cluster")
    out = base / "out"
    out.mkdir()
    hidden = [fmu_dir, out] + [REPO / "fmus"] * (REPO / "fmus").is_dir()
    c = Cluster(base, hidden)
    c.out = out
    try:
        c.start()
        from distributed import Client

        with Client(c.address, timeout="20s") as client:
            client.wait_for_workers(2, timeout=40)
            # the workers really do not see the client's files
            seen = client.run(os.path.exists, str(fmu_dir / "GliderPlant.fmu"))
            assert seen and not any(seen.values()), seen
        yield c
    finally:
        left = c.stop()
        assert not left, f"processes left behind: {left}"


def cli(args: list[str], cwd: Path, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "glider_cosim.cli", *args], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, **kw)  # fmt: skip


def test_sweep_with_trajectories_completes(cluster, fmu_dir):
    out = cluster.out / "traj"
    # K_c = 0.05: the observer's estimate stalls at 2.58 s, the others run
    p = cli(["sweep", "--scheduler", cluster.address, "--param", "controller.K_c=8,12,0.05",
             "--stop-time", "4", "--fmu-dir", str(fmu_dir), "--out", str(out),
             "--trajectories", "--no-plots"], cluster.base)  # fmt: skip
    stdout, stderr = p.communicate(timeout=90)
    assert p.returncode == 1, stderr
    assert "3 runs (0 already done), 3 run now, 1 failed" in stdout
    table = rows(out / "sweep.csv")
    assert sorted(r["status"] for r in table) == ["ok", "ok", "stopped"]
    assert "Port 8787" not in stderr and "dashboard" not in stdout
    files = {f.stem: f for f in (out / "trajectories").iterdir()}
    ok = [r["run_id"] for r in table if r["status"] == "ok"]
    # written by the client: the stopped run's too, up to its failure
    assert sorted(files) == sorted(r["run_id"] for r in table)
    (stopped,) = (r["run_id"] for r in table if r["status"] == "stopped")
    assert 1 < len(files[stopped].read_text().splitlines()) < 1 + 201
    for rid in ok:
        lines = files[rid].read_text().splitlines()
        assert lines[0].startswith("time,plant.theta_meas")
        assert len(lines) == 1 + 201  # t = 0 .. 4 s at 50 Hz
        assert float(lines[-1].split(",")[0]) == pytest.approx(4.0)


def test_a_sigkilled_worker_has_its_runs_retried(cluster, fmu_dir):
    from distributed import Client

    sc = load_scenario(None)
    runs = expand([parse_param("controller.K_c=8:30:24")], sc, fmu_dir, stop_time=20.0)
    out = cluster.out / "worker-kill"
    with Client(cluster.address, timeout="20s") as client:
        client.wait_for_workers(2, timeout=40)
        pids = client.run(os.getpid)
        result = {}

        def sweep():
            result["r"] = run_sweep(sc, runs, out, client, fmu_dir, stop_time=20.0)

        t = threading.Thread(target=sweep)
        t.start()
        deadline = time.time() + 60
        while time.time() < deadline and t.is_alive():
            if (out / "sweep.csv").exists() and len(rows(out / "sweep.csv")) >= 2:
                break
            time.sleep(0.02)
        assert t.is_alive(), "the sweep ended before the worker could be killed"
        os.kill(sorted(pids.values())[0], signal.SIGKILL)
        t.join(timeout=90)
        assert not t.is_alive()
        client.wait_for_workers(2, timeout=40)  # the nanny started a new worker process
        assert set(client.run(os.getpid).values()) != set(pids.values())
    table = rows(out / "sweep.csv")
    assert sorted(r["run_id"] for r in table) == sorted(r["run_id"] for r in runs)
    assert all(r["status"] == "ok" for r in table)
    assert result["r"].failed == 0 and result["r"].done == 24


def test_a_killed_client_resumes_without_redoing_runs(cluster, fmu_dir):
    out = cluster.out / "client-kill"
    # 40 runs; K_c = 0.05 fails (the observer's estimate stalls at 2.58 s)
    kc = ",".join(["0.05", *(str(k) for k in range(5, 44))])
    args = ["sweep", "--scheduler", cluster.address, "--param", f"controller.K_c={kc}",
            "--stop-time", "20", "--fmu-dir", str(fmu_dir), "--out", str(out),
            "--no-plots"]  # fmt: skip
    p = cli(args, cluster.base)
    deadline = time.time() + 60
    n = 0
    while time.time() < deadline and p.poll() is None:
        if (out / "sweep.csv").exists():
            n = (out / "sweep.csv").read_bytes().count(b"\n") - 1
            if n >= 4:
                break
        time.sleep(0.01)
    assert p.poll() is None, "the sweep ended before the client could be killed"
    os.killpg(p.pid, signal.SIGKILL)
    p.communicate(timeout=10)
    before = rows(out / "sweep.csv")
    assert 4 <= len(before) < 40
    again = cli(args, cluster.base)
    stdout, stderr = again.communicate(timeout=120)
    k = len(before)
    m = re.search(r"40 runs \((\d+) already done\), (\d+) run now", stdout)
    assert m, stdout + stderr
    assert (int(m.group(1)), int(m.group(2))) == (k, 40 - k)  # nothing redone
    after = rows(out / "sweep.csv")
    assert after[:k] == before  # the rows of the first call are kept as they were
    ids = [r["run_id"] for r in after]
    assert len(ids) == len(set(ids)) == 40
    # K_c = 0.05 fails (in the first call or the second): the exit code counts it
    assert [r["controller.K_c"] for r in after if r["status"] != "ok"] == ["0.05"]
    assert again.returncode == 1 and "1 of 40 failed overall" in stdout
