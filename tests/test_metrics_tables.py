"""The run's metrics on numpy arrays (``runner/metrics.py``, ``runner/outcome.py``): every
outcome met on a few hundred synthetic trajectories; the recorders' tables (row-major,
the columns strided) give the same bits as numpy arrays; the run's table is a numpy
array on access."""

from __future__ import annotations

import math
from array import array
from types import SimpleNamespace

import numpy as np

from glider_cosim.runner import metrics as metrics_module
from glider_cosim.runner.metrics import compute_metrics, glide_metrics, wrapped_rms
from glider_cosim.runner.outcome import OUTCOMES, wrap_angle
from glider_cosim.runner.recorders import ArrayRecorder, Table

THETA_GE = -0.3940432938639892  # the default glide's equilibrium, rad


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


def test_every_outcome_is_met_and_a_table_gives_the_arrays_bits(monkeypatch):
    """Every outcome met on the synthetic trajectories; the metrics of a recorded table
    (:func:`compute_metrics`: a :class:`Table` or a 2-D array, its columns strided) are
    :func:`glide_metrics`' of the columns, bit for bit."""
    seen: dict[str, int] = {}
    sim = SimpleNamespace(coupling="gauss-seidel", step_size=0.02,
                          system=SimpleNamespace(parameters={"plant": {}, "controller": {}},
                                                 events=[]))  # fmt: skip
    scenario = SimpleNamespace(name="t", source="<test>")
    columns = ["time", "a", "plant.theta_g", "b", "controller.delta_cmd"]
    for kind, t, theta_g, delta_cmd, t_on, completed in trajectories(np.random.default_rng(48)):
        theta_ge = 0.0 if kind == "pi boundary, held" and theta_g[0] == theta_g[-1] else THETA_GE
        want = glide_metrics(t, theta_g, delta_cmd, theta_ge, t_on, completed=completed)
        seen[str(want["outcome"])] = seen.get(str(want["outcome"]), 0) + 1
        # the scenario's glide and takeover: this trajectory's
        monkeypatch.setattr(metrics_module, "reference_glide", lambda *a, g=theta_ge: (g, 0.5))
        monkeypatch.setattr(metrics_module, "takeover_time", lambda *a, on=t_on: on)
        status = "ok" if completed else "stopped"
        for data in (table_of(t, theta_g, delta_cmd),
                     np.column_stack([t, t, theta_g, t, delta_cmd])):  # fmt: skip
            got = compute_metrics(columns, data, scenario, sim, status)
            same_bits({k: got[k] for k in want}, want)
    assert set(seen) == {*OUTCOMES, "None"}, seen
    assert min(seen.values()) >= 8 and seen["settled"] >= 50, seen


def test_the_estimation_rms_of_a_table_is_numpys():
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


def test_a_tables_csv_lines_are_the_arrays():
    """The sweep's trajectories: a Table's CSV text is the array's, the same bytes."""
    from glider_cosim.runner.recorders import csv_lines

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


def test_the_angle_wrap_is_numpys_mod_bit_for_bit():
    """``wrap_angle`` (fmod and a correction, for speed) gives ``np.mod``'s bits: random
    values of every magnitude, the multiples of the period and their neighbours, zeros,
    the smallest subnormals, NaN and the infinities; degrees too."""
    rng = np.random.default_rng(53)
    for period in (2.0 * math.pi, 360.0):
        half = 0.5 * period
        x = np.concatenate(
            [rng.normal(size=20000) * s for s in (1e-300, 1e-9, 1.0, 4.0, 1e3, 1e9, 1e17)]
            + [np.arange(-6, 7) * half + d for d in (0.0, 1e-12, -1e-12)]
            + [np.array([0.0, -0.0, 5e-324, -5e-324, np.nextafter(half, 0), -half, half])]
        )  # fmt: skip
        with np.errstate(invalid="ignore"):
            want = np.mod(x + half, period) - half
        got = wrap_angle(x, period)
        assert got.view(np.uint64).tolist() == want.view(np.uint64).tolist()
        with np.errstate(invalid="ignore"):
            special = wrap_angle(np.array([np.nan, np.inf, -np.inf]), period)
        assert np.isnan(special).all()
    assert float(wrap_angle(math.pi)) == -math.pi and float(wrap_angle(-math.pi)) == -math.pi
