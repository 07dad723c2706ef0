"""The run's metrics without numpy (issue 48): the C kernel (cosim/runner/glidemetrics.c)
against the numpy code (:func:`glide_metrics`, :func:`classify`), bit for bit, on a few
hundred synthetic trajectories of every outcome; and the run's recorder and metrics path
in a process where numpy cannot be imported."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from array import array
from pathlib import Path

import numpy as np
import pytest

from glider_cosim.master import fastloop
from glider_cosim.runner import metrics as metrics_module
from glider_cosim.runner.metrics import _glide_metrics_c, glide_metrics, wrapped_rms
from glider_cosim.runner.outcome import OUTCOMES, wrap_angle
from glider_cosim.runner.recorders import ArrayRecorder, Table

ROOT = Path(__file__).resolve().parents[1]
THETA_GE = -0.3940432938639892  # the default glide's equilibrium, rad


@pytest.fixture(scope="module", autouse=True)
def lib():
    if fastloop.library() is None:
        pytest.skip("no C compiler for the helper library")


def bits(value):
    """A value as comparable bits: a float's hex (-0.0 and NaN told apart), a list's
    items, anything else as it is, with its type."""
    if isinstance(value, float):
        return ("float", value.hex())
    if isinstance(value, list | tuple):
        return (type(value).__name__, [bits(v) for v in value])
    return (type(value).__name__, value)


def same_bits(got: dict, want: dict) -> None:
    assert list(got) == list(want), (list(got), list(want))
    for k in want:
        assert bits(got[k]) == bits(want[k]), (k, got[k], want[k])


def table_of(t, theta_g, delta_cmd) -> Table:
    """A recorded table: row-major, time first, the columns strided among others."""
    rows = np.column_stack([t, np.sin(t), theta_g, np.cos(t), delta_cmd])
    return Table(array("d", rows.tobytes()), len(t), 5)


WHICH = (0, 2, 4)


def trajectories(rng: np.random.Generator):
    """``(name, t, theta_g, delta_cmd, t_on, completed)`` of every kind."""
    for i in range(300):
        h = rng.choice([0.02, 0.01, 0.05, 0.1])
        n = int(rng.choice([3001, 1201, 601, 2000, 150, 40]))
        t = np.arange(n) * h + rng.choice([0.0, 0.0, 3.0])
        tau = t - t[0]
        amp = rng.uniform(0.05, 1.0) * rng.choice([-1, 1])
        w = rng.uniform(0.5, 4.0)
        kind = ["settled", "not settled", "limit cycle", "diverging", "grows", "tumbling",
                "loops once", "offset", "noise"][i % 9]  # fmt: skip
        if kind == "settled":
            e = amp * np.exp(-rng.uniform(0.2, 2.0) * tau) * np.cos(w * tau)
        elif kind == "not settled":
            e = amp * np.exp(-rng.uniform(0.005, 0.03) * tau) * np.cos(w * tau)
        elif kind == "limit cycle":
            e = amp * np.cos(w * tau)
        elif kind == "diverging":
            e = 0.01 * amp * np.exp(rng.uniform(0.02, 0.1) * tau) * np.cos(w * tau)
        elif kind == "grows":
            e = 0.01 * amp * np.exp(rng.uniform(0.02, 0.1) * tau)
        elif kind == "tumbling":
            e = amp + rng.uniform(0.3, 3.0) * rng.choice([-1, 1]) * tau
        elif kind == "loops once":  # a full turn, then settles about the same glide
            e = amp * np.exp(-tau) + 2 * math.pi * (1 - np.exp(-3 * tau)) * np.sign(amp)
        elif kind == "offset":
            e = amp * np.exp(-tau) + 0.05 * amp
        else:
            e = 0.3 * amp * np.exp(-0.5 * tau) + rng.normal(0, 1e-4, n)
        e = e + rng.normal(0, 1e-7, n) * (i % 2)
        theta_g = THETA_GE + e
        delta_cmd = rng.normal(0, 0.05, n)
        t_on = [float(t[0]), float(t[0]), float(t[n // 5]), float(t[n // 5]) + 0.3 * h,
                None, float(t[-1]) + 1.0][i % 6]  # fmt: skip
        yield kind, t, theta_g, delta_cmd, t_on, i % 7 != 3
    # the edges: very short, zero initial error, the +-pi boundary of the wrap
    for n in (1, 2, 3):
        t = np.arange(n) * 0.02
        yield "short", t, THETA_GE + 0.1 * np.ones(n), np.ones(n), 0.0, True
        yield "short", t, THETA_GE + 0.1 * np.ones(n), np.ones(n), 0.0, False
    t = np.arange(3001) * 0.02
    zero = np.zeros(3001)
    yield "zero error", t, THETA_GE + zero, zero, 0.0, True
    yield "zero error, then away", t, THETA_GE + 1e-3 * np.sin(t), zero, 0.0, True
    yield "zero error, stopped", t, THETA_GE + zero, zero, 0.0, False
    for e0 in (math.pi, -math.pi, np.nextafter(math.pi, 0), np.nextafter(-math.pi, 0),
               3 * math.pi, -3 * math.pi, 2 * math.pi):  # fmt: skip
        e = e0 * np.exp(-2.0 * t)
        yield "pi boundary", t, THETA_GE + e, 0.01 * e, 0.0, True
        e = np.full(3001, e0)
        yield "pi boundary, held", t, THETA_GE + e, zero, 0.0, True
        yield "pi boundary, held", t, e, zero, 0.0, True  # theta_ge passed as 0
    e = math.pi * np.cos(t)  # a limit cycle across the +-pi wrap
    yield "pi boundary, cycle", t, THETA_GE + e, zero, 0.0, True


def test_the_kernel_gives_the_numpy_metrics_bit_for_bit():
    """Every float of the metrics of every trajectory, and each outcome met: the kernel
    computes them all, numpy fitting the points it hands back where a fit decides
    (not settled, limit cycle, diverging)."""
    seen: dict[str, int] = {}
    for kind, t, theta_g, delta_cmd, t_on, completed in trajectories(np.random.default_rng(48)):
        theta_ge = 0.0 if kind == "pi boundary, held" and theta_g[0] == theta_g[-1] else THETA_GE
        want = glide_metrics(t, theta_g, delta_cmd, theta_ge, t_on, completed=completed)
        seen[str(want["outcome"])] = seen.get(str(want["outcome"]), 0) + 1
        got = _glide_metrics_c(table_of(t, theta_g, delta_cmd), WHICH, theta_ge, t_on, completed)
        assert got is not None, (kind, want)
        same_bits(got, want)
        # a numpy table (what the API may hand over) gives the same
        rows = np.column_stack([t, t, theta_g, t, delta_cmd])
        same_bits(_glide_metrics_c(rows, WHICH, theta_ge, t_on, completed), want)
    assert set(seen) == {*OUTCOMES, "None"}, seen
    assert min(seen.values()) >= 8 and seen["settled"] >= 50, seen


def test_a_value_not_finite_is_left_to_numpy():
    t = np.arange(3001) * 0.02
    e = 0.2 * np.exp(-t)
    theta = THETA_GE + e
    theta[-1] = math.nan
    assert _glide_metrics_c(table_of(t, theta, e), WHICH, THETA_GE, 0.0, False) is None
    t2 = t.copy()
    t2[7] = t2[6]  # time not strictly increasing: numpy raises
    assert _glide_metrics_c(table_of(t2, THETA_GE + e, e), WHICH, THETA_GE, 0.0, True) is None


def test_where_a_fit_decides_numpy_fits_the_kernels_points(monkeypatch):
    """A limit cycle: the fit is numpy's (np.polyfit, called once), on the peaks."""
    from glider_cosim.runner import outcome

    t = np.arange(3001) * 0.02
    e = 0.2 * np.cos(2 * t)
    fits = []
    real = outcome._fit_rate
    monkeypatch.setattr(outcome, "_fit_rate", lambda x, y: fits.append(len(x)) or real(x, y))
    got = _glide_metrics_c(table_of(t, THETA_GE + e, e), WHICH, THETA_GE, 0.0, True)
    assert got["outcome"] == "limit cycle" and len(fits) == 1 and 10 < fits[0] < 30, fits
    monkeypatch.undo()
    same_bits(got, glide_metrics(t, THETA_GE + e, e, THETA_GE, 0.0))


def test_the_estimation_rms_is_numpys_bit_for_bit():
    rng = np.random.default_rng(5)
    for n in (1, 2, 7, 8, 9, 127, 128, 129, 300, 3001, 10000):
        a = rng.normal(0, 2.0, n) * rng.choice([1e-6, 1.0, 4.0])
        b = rng.normal(0, 2.0, n)
        a[: n // 3] = b[: n // 3] + math.pi  # the wrap's boundary
        rows = np.column_stack([np.arange(n), a, b])
        want = float(np.sqrt(np.mean(wrap_angle(rows[:, 1] - rows[:, 2]) ** 2)))
        table = Table(array("d", rows.tobytes()), n, 3)
        assert wrapped_rms(table, 1, 2).hex() == want.hex(), n
        assert wrapped_rms(rows, 1, 2).hex() == want.hex(), n


def test_without_the_c_helper_numpy_gives_the_metrics(monkeypatch):
    t = np.arange(3001) * 0.02
    e = 0.2 * np.exp(-t)
    table = table_of(t, THETA_GE + e, e)
    with_c = _glide_metrics_c(table, WHICH, THETA_GE, 0.0, True)
    monkeypatch.setattr(metrics_module, "_KERNEL", [None])
    assert _glide_metrics_c(table, WHICH, THETA_GE, 0.0, True) is None
    want = float(np.sqrt(np.mean(wrap_angle((THETA_GE + e) - e) ** 2)))
    assert wrapped_rms(table, 2, 4).hex() == want.hex()
    assert with_c["outcome"] == "settled"


def test_the_recorder_keeps_the_rows_it_is_handed():
    import ctypes

    rec = ArrayRecorder()
    rec.start(["time", "a", "b"])
    rec.row((0.0, 1.0, -0.0))
    block = (ctypes.c_double * 9)(*range(1, 10))
    rec.rows_block(block, 2, 3)  # the first 2 rows of the buffer
    rec.row([9.5, math.inf, 1e-300])
    assert len(rec) == 4
    want = np.array([[0.0, 1.0, -0.0], [1, 2, 3], [4, 5, 6], [9.5, math.inf, 1e-300]])
    assert rec.array().tobytes() == want.tobytes()
    table = rec.table()
    assert (len(table), table.ncol, table.value(-1, 0)) == (4, 3, 9.5)
    assert table.array().tobytes() == want.tobytes()
    assert ArrayRecorder().array(3).shape == (0, 3)


BLOCK_NUMPY = r"""
import builtins, importlib.abc, sys

class NoNumpy(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "numpy" or name.startswith("numpy."):
            raise ImportError(f"numpy is blocked (imported as {name})")
        return None

sys.meta_path.insert(0, NoNumpy())
"""

NO_NUMPY_RUN = r"""
import ctypes, json, math, sys
from pathlib import Path
from types import SimpleNamespace

from glider_cosim.runner.metrics import compute_metrics, wrapped_rms
from glider_cosim.runner.recorders import ArrayRecorder, CsvRecorder

out = Path(sys.argv[1])
columns = ["time", "plant.theta_g", "observer.theta_g_hat", "controller.delta_cmd"]
rec = CsvRecorder(out / "results.csv", keep=ArrayRecorder())
rec.start(columns)
theta_ge = -0.3940432938639892
rows = []
for k in range(3001):
    t = 0.02 * k
    e = 0.3 * math.exp(-0.8 * t) * math.cos(1.7 * t)
    rows.append((t, theta_ge + e, theta_ge + 1.01 * e, -0.5 * e))
for r in rows[:200]:
    rec.row(r)
block = (ctypes.c_double * (len(rows[200:]) * 4))(*[v for r in rows[200:] for v in r])
rec.rows_block(block, len(rows) - 200, 4)
rec.close()
table = rec.keep.table()
plant = {}
sim = SimpleNamespace(coupling="gauss-seidel", step_size=0.02,
                      system=SimpleNamespace(parameters={"plant": plant, "controller": {}},
                                             events=[]))
scenario = SimpleNamespace(name="no-numpy", source="<test>")
m = compute_metrics(columns, table, scenario, sim)
m["estimation_rms_rad"] = wrapped_rms(table, 2, 1)
print(json.dumps({"numpy": "numpy" in sys.modules, "metrics": m}))
"""


def test_the_runs_recorders_and_metrics_need_no_numpy(tmp_path):
    """The CLI run's path after the loop: the CSV recorder (keeping the rows) and the
    metrics of the kept table, in a process where importing numpy fails; the same
    metrics as numpy's."""
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    proc = subprocess.run(
        [sys.executable, "-c", BLOCK_NUMPY + NO_NUMPY_RUN, str(tmp_path)],
        capture_output=True, text=True, env=env, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    got = json.loads(proc.stdout)
    assert got["numpy"] is False
    m = got["metrics"]
    assert m["outcome"] == "settled" and m["rows"] == 3001, m
    data = np.loadtxt(tmp_path / "results.csv", delimiter=",", skiprows=1)
    want = glide_metrics(data[:, 0].copy(), data[:, 1].copy(), data[:, 3].copy(),
                         m["theta_ge_rad"], 0.0)  # fmt: skip
    for k, v in want.items():
        assert bits(m[k]) == bits(v), (k, m[k], v)
    rms = float(np.sqrt(np.mean(wrap_angle(data[:, 2] - data[:, 1]) ** 2)))
    assert m["estimation_rms_rad"].hex() == rms.hex()


@pytest.mark.parametrize("helper", ["1", "0"])
def test_a_tables_csv_lines_are_the_arrays(helper, monkeypatch):
    """The sweep's trajectories: a Table's CSV text without numpy, the same bytes."""
    from glider_cosim.runner.recorders import csv_lines

    monkeypatch.setenv("GLIDER_COSIM_FASTLOOP", helper)
    rows = np.random.default_rng(3).normal(size=(40, 3)) * 1e3
    rows[2, 1], rows[5, 0], rows[7, 2] = -0.0, math.inf, 1e-310
    table = Table(array("d", rows.tobytes()), 40, 3)
    assert csv_lines(table) == csv_lines(rows)
    assert csv_lines(table).count(b"\n") == 40


def test_a_run_results_data_is_a_numpy_array_made_on_access():
    from glider_cosim.runner.run import RunResult

    rows = np.arange(12, dtype=float).reshape(4, 3)
    result = RunResult(None, ["time", "a", "b"], Table(array("d", rows.tobytes()), 4, 3), {})
    assert isinstance(result.__dict__["_data"], Table)  # kept as the run handed it over
    assert isinstance(result.data, np.ndarray) and result.data.tobytes() == rows.tobytes()
    assert result.data is result.data  # made once
    assert result.column("b").tolist() == [2.0, 5.0, 8.0, 11.0]
    same = RunResult(None, ["time", "a", "b"], rows, {})
    assert same.data is rows and same == RunResult(None, ["time", "a", "b"], rows, {})
