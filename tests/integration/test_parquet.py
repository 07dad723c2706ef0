"""``--format parquet``: the same rows as ``results.csv``, float64 as they are."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest

from glider_cosim.runner import simulate

pytestmark = pytest.mark.integration


def test_parquet_holds_the_csv_rows_exactly(native_dir, tmp_path):
    a = simulate("default", tmp_path / "csv", fmu_dir=native_dir, build=False, plots=False)
    b = simulate("default", tmp_path / "pq", fmu_dir=native_dir, build=False, plots=False,
                 results_format="parquet")  # fmt: skip
    assert a.status == b.status == "ok"
    table = pq.read_table(tmp_path / "pq" / "results.parquet")
    assert table.schema.names == a.columns
    stored = np.column_stack([table.column(c).to_numpy() for c in a.columns])
    csv = np.loadtxt(tmp_path / "csv" / "results.csv", delimiter=",", skiprows=1)
    assert stored.shape == (3001, len(a.columns))
    assert np.array_equal(stored, csv)  # %.17g text reads back bit for bit: the same values
    assert np.array_equal(stored, b.data) and b.metrics["status"] == "ok"
    assert a.metrics["settling_time_s"] == b.metrics["settling_time_s"]


def test_a_stopped_run_keeps_its_rows_in_parquet(native_dir, tmp_path):
    r = simulate("sec53-literal", tmp_path, fmu_dir=native_dir, build=False, plots=False,
                 results_format="parquet")  # fmt: skip
    assert r.status == "stopped"
    table = pq.read_table(tmp_path / "results.parquet")
    assert table.num_rows == len(r.data) > 100  # every row up to the stop


def test_cli_format_parquet_and_a_bad_format(native_dir, tmp_path):
    run = [sys.executable, "-m", "glider_cosim.cli", "run", "--fmu-dir", str(native_dir),
           "--no-plots", "--stop-time", "2", "--out", str(tmp_path / "o")]  # fmt: skip
    p = subprocess.run([*run, "--format", "parquet"], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "results.parquet" in p.stdout and (tmp_path / "o" / "results.parquet").is_file()
    p = subprocess.run([*run, "--format", "xlsx"], capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1
    assert "--format" in p.stderr and "'xlsx'" in p.stderr
