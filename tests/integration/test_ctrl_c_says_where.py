"""Ctrl-C (a real SIGINT to a real process) names where the results are and how to go on:
``run`` the rows kept and the command to run again, ``sweep`` the runs kept and the
command that resumes it (which does resume)."""

from __future__ import annotations

import csv
import json
import re
import shlex
import signal
import subprocess
import sys
import time

import pytest

pytestmark = pytest.mark.integration

CLI = "from glider_cosim.cli import console_main; console_main()"


def _as_in_a_terminal() -> None:
    """SIGINT as a shell in a terminal leaves it: not ignored (a test session started in
    the background of a script inherits it ignored, and so would the command)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", CLI, *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=_as_in_a_terminal)  # fmt: skip


def wait_for(predicate, what: str, timeout: float = 120) -> None:
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return
        time.sleep(0.05)
    raise AssertionError(f"{what} did not happen in {timeout} s")


def test_ctrl_c_in_a_sweep_names_the_table_and_the_resume_command(native_dir, tmp_path):
    out = tmp_path / "out"
    table = out / "sweep.csv"
    args = ["sweep", "--param", "controller.K_c=6:30:100", "--stop-time", "3000",
            "--workers", "1", "--fmu-dir", str(native_dir), "--out", str(out), "--no-plots",
            "--restart"]  # fmt: skip
    p = start(*args)
    wait_for(lambda: table.is_file() and table.read_bytes().count(b"\n") > 1, "a first row")
    assert p.poll() is None, "the sweep ended before it could be interrupted"
    p.send_signal(signal.SIGINT)
    out_text, err = p.communicate(timeout=120)
    assert p.returncode == 130, out_text + err
    with open(table, newline="") as f:
        kept = len(list(csv.DictReader(f)))
    assert 0 < kept < 100
    resume = shlex.join(["glider-cosim", *(a for a in args if a != "--restart")])
    assert err.splitlines()[-1] == (
        f"glider-cosim sweep: error: interrupted; results so far are written: {kept} of 100 "
        f"runs in {table}; resume with: {resume}"
    ), err
    # the command it names resumes the sweep
    again = subprocess.run([sys.executable, "-c", CLI, *shlex.split(resume)[1:]],
                           capture_output=True, text=True, timeout=300)  # fmt: skip
    assert again.returncode == 0, again.stderr
    assert f"100 runs ({kept} already done), {100 - kept} run now" in again.stdout


def test_ctrl_c_in_a_run_names_the_rows_kept_and_the_command(fmu_dir, tmp_path):
    out = tmp_path / "o"
    args = ["run", "--stop-time", "3600", "--out", str(out), "--fmu-dir", str(fmu_dir),
            "--no-plots"]  # fmt: skip
    p = start(*args)
    results = out / "results.csv"
    wait_for(lambda: results.is_file() and results.stat().st_size > 100_000, "100 kB of rows")
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    m = json.loads((out / "metrics.json").read_text())
    assert m["rows"] == len(results.read_text().splitlines()) - 1 > 100
    line = err.splitlines()[-1]
    assert re.fullmatch(
        rf"glider-cosim run: error: interrupted; results so far are written: {m['rows']} rows "
        rf"to t = [0-9.]+ s in {re.escape(str(out))}; run it again with: "
        + re.escape(shlex.join(["glider-cosim", *args])),
        line,
    ), line
    t = float(re.search(r"to t = ([0-9.]+) s", line).group(1))
    assert t == pytest.approx(m["end_time_s"], abs=1e-9)
