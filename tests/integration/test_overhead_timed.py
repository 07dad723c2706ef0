"""bench/overhead_timed.py runs (one short round) and its differences are its own figures'."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

SCRIPT = Path(__file__).parents[2] / "bench" / "overhead_timed.py"


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True,
                          text=True, timeout=600)  # fmt: skip


def test_one_round_gives_every_figure_and_its_differences(native_dir):
    p = _run("--rounds", "1", "--runs", "2", "--fmu-dir", str(native_dir), "--json")
    assert p.returncode == 0, p.stderr
    r = json.loads(p.stdout.splitlines()[-1])
    kinds = ("floor", "advance", "reused_run", "fresh_run")
    for k in kinds:
        assert 0.05 < r[f"{k}_us_per_macro_step"] < 50, (k, r)
    n = r["steps_per_run"]
    assert n == 3000
    for pre in ("", "median_"):
        f = {k: r[f"{pre}{k}_us_per_macro_step"] for k in kinds}
        assert r[f"{pre}loop_overhead_us_per_macro_step"] == pytest.approx(
            f["advance"] - f["floor"], abs=2e-4
        )
        assert r[f"{pre}overhead_us_per_macro_step"] == pytest.approx(
            f["fresh_run"] - f["floor"], abs=2e-4
        )
        assert r[f"{pre}run_prologue_us"] == pytest.approx(
            (f["reused_run"] - f["advance"]) * n, abs=1.0
        )
        assert r[f"{pre}fresh_instances_us"] == pytest.approx(
            (f["fresh_run"] - f["reused_run"]) * n, abs=1.0
        )


def test_bad_counts_are_one_line_errors():
    p = _run("--rounds", "0")
    assert p.returncode != 0
    assert p.stderr.strip() == "--rounds 0 --runs 20: expected both >= 1"
