"""Paced runs (``--real-time``): the wall clock, metrics.json's ``real_time``, the same
rows as an unpaced run, the lateness limit, and Ctrl-C as in any run."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from glider_cosim.realtime.pacing import RealTime
from glider_cosim.runner import simulate

pytestmark = pytest.mark.integration
CLI = "import sys; from glider_cosim.cli.main import console_main; console_main()"


def test_a_paced_run_takes_its_wall_time_and_equals_the_unpaced_run(native_dir):
    free = simulate("default", None, fmu_dir=native_dir, build=False, stop_time=1.0)
    t = time.monotonic()
    paced = simulate("default", None, fmu_dir=native_dir, build=False, stop_time=1.0,
                     real_time=RealTime(rtf=2.0))  # fmt: skip
    wall = time.monotonic() - t
    assert wall >= 0.5 - 0.01  # 1 s simulated at twice real time
    assert np.array_equal(free.data, paced.data)  # bit for bit
    rt = paced.metrics["real_time"]
    assert rt["rtf_target"] == 2.0 and 1.0 < rt["rtf_achieved"] <= 2.001
    assert rt["points"] == len(paced.data) == 51
    assert set(rt["lateness_ms"]) == {"p50", "p99", "max"} and rt["overruns"] >= 0
    assert "real_time" not in free.metrics


def test_cli_prints_the_line_and_the_lateness_limit_stops_cleanly(native_dir, tmp_path):
    out = tmp_path / "o"
    base = [sys.executable, "-c", CLI, "run", "--fmu-dir", str(native_dir), "--no-plots"]
    args = ["--out", str(out), "--stop-time", "0.4", "--real-time", "--rtf", "4"]
    p = subprocess.run(base + args, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "  real time: rtf " in p.stdout and "(target 4)" in p.stdout
    m = json.loads((out / "metrics.json").read_text())
    assert m["real_time"]["rtf_target"] == 4 and m["run"]["options"]["--real-time"] is True
    # 20 ns per point: every point is later than the one before, 0.5 ms is soon passed
    p = subprocess.run(base + ["--out", str(out), "--real-time", "--rtf", "1e6",
                               "--max-lateness-ms", "0.5"], capture_output=True, text=True,
                       timeout=120)  # fmt: skip
    assert p.returncode == 1
    assert "run stopped: real time: the communication point at t = " in p.stderr
    assert "ms late, more than --max-lateness-ms 0.5" in p.stderr and "Traceback" not in p.stderr
    m = json.loads((out / "metrics.json").read_text())
    rows = (out / "results.csv").read_text().splitlines()
    assert m["status"] == "stopped" and 1 < m["rows"] == len(rows) - 1 < 3001
    assert m["real_time"]["lateness_ms"]["max"] > 0.5
    p = subprocess.run(base + ["--out", str(out), "--rtf", "2"], capture_output=True, text=True,
                       timeout=60)  # fmt: skip
    assert p.returncode == 2 and "--rtf needs --real-time" in p.stderr
    p = subprocess.run(base + ["--out", str(out), "--spin-ms", "20"], capture_output=True,
                       text=True, timeout=60)  # fmt: skip
    assert p.returncode == 2 and "--spin-ms needs --real-time" in p.stderr
    p = subprocess.run(base + ["--out", str(out), "--real-time", "--spin-ms", "-1"],
                       capture_output=True, text=True, timeout=60)  # fmt: skip
    assert p.returncode == 2 and "'-1' is invalid: expected a finite number >= 0" in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1
    p = subprocess.run(base + ["--out", str(out), "--stop-time", "0.2", "--real-time",
                               "--rtf", "4", "--spin-ms", "5"], capture_output=True,
                       text=True, timeout=120)  # fmt: skip
    assert p.returncode == 0, p.stderr
    m = json.loads((out / "metrics.json").read_text())
    assert m["real_time"]["spin_ms"] == 5 and m["run"]["options"]["--spin-ms"] == 5


def test_ctrl_c_in_a_paced_run_writes_the_results_so_far(native_dir, tmp_path):
    out = tmp_path / "o"
    p = subprocess.Popen(
        [sys.executable, "-c", CLI, "run", "--fmu-dir", str(native_dir), "--no-plots", "--out",
         str(out), "--real-time", "--rtf", "2"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    results = out / "results.csv"
    deadline = time.time() + 60
    while time.time() < deadline and (not results.exists() or results.stat().st_size < 5000):
        time.sleep(0.05)
    os.kill(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert "interrupted; results so far are written" in err
    m = json.loads((out / "metrics.json").read_text())
    assert m["status"] == "interrupted" and m["rows"] == len(results.read_text().splitlines()) - 1
    assert m["real_time"]["points"] == m["rows"]


def test_a_paced_run_freezes_the_objects_before_it_and_unfreezes_them_after(native_dir):
    import gc

    frozen: list[tuple[int, int]] = []  # (generation, objects frozen) of every collection

    def seen(phase, info):
        if phase == "start":
            frozen.append((info["generation"], gc.get_freeze_count()))

    before, threshold = gc.get_freeze_count(), gc.get_threshold()
    gc.set_threshold(50)  # collections during the 0.5 s of the loop, whatever it allocates
    gc.callbacks.append(seen)
    try:
        simulate("default", None, fmu_dir=native_dir, build=False, stop_time=2.0,
                 real_time=RealTime(rtf=4.0))  # fmt: skip
    finally:
        gc.callbacks.remove(seen)
        gc.set_threshold(*threshold)
    # the full collection right before the loop, then the loop's, with the rest frozen
    full = [i for i, (gen, n) in enumerate(frozen) if gen == 2 and n == before]
    assert full, frozen
    after = [n for gen, n in frozen[full[-1] + 1 :]]
    assert len(after) >= 2 and after[0] > before + 1000, frozen[full[-1] :]  # in the loop
    assert gc.get_freeze_count() == before
