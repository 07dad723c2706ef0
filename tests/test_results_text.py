"""The text of every CSV glider-cosim writes (``results.csv``, a sweep's trajectories, the
reference CSVs): each double as Python's ``repr`` writes it, the shortest text that reads
back to the same bits, through the standard library (``runner/recorders.py``); and the
CSV recorder's behaviour: the rows it keeps, a failure's rows written, errors named."""

from __future__ import annotations

import ctypes
import importlib
import math
from pathlib import Path

import numpy as np
import pytest

from glider_cosim.runner import recorders
from glider_cosim.runner.recorders import ArrayRecorder, CsvRecorder, csv_lines, repr_row

#: a golden check of the text: if any of these lines changes, results.csv changes
GOLDEN = [
    ([0.0, 0.02, 0.1, 1e-05, -0.0], "0.0,0.02,0.1,1e-05,-0.0\n"),
    ([math.inf, -math.inf, math.nan, 123.0, 1e16], "inf,-inf,nan,123.0,1e+16\n"),
    ([5e-324, 1.7976931348623157e308, -0.3940432938639892, 2.220446049250313e-16, 1 / 3],
     "5e-324,1.7976931348623157e+308,-0.3940432938639892,2.220446049250313e-16,"
     "0.3333333333333333\n"),
    ([0.1 + 0.2, 1234567.125, 1e23, 1e22, 60.00000000000001],
     "0.30000000000000004,1234567.125,1e+23,1e+22,60.00000000000001\n"),
]  # fmt: skip


def special_values() -> np.ndarray:
    """Zeros, infinities, NaN, the extremes, subnormals, powers of two and ten and their
    neighbours."""
    v = [0.0, -0.0, math.inf, -math.inf, math.nan, 5e-324, -5e-324, 2.2250738585072014e-308,
         1.7976931348623157e308]  # fmt: skip
    for e in range(-1074, 1024, 7):
        x = math.ldexp(1.0, e)
        v += [x, math.nextafter(x, 0.0), math.nextafter(x, math.inf), -x]
    for e in range(-320, 309, 3):
        x = float(f"1e{e}")
        v += [x, math.nextafter(x, 0.0), math.nextafter(x, math.inf)]
    return np.array(v)


def random_values(n: int, seed: int) -> np.ndarray:
    """``n`` doubles of uniformly random bit patterns (every exponent and sign, NaNs too),
    and ``n`` of a simulation's magnitudes."""
    rng = np.random.default_rng(seed)
    bits = rng.integers(0, 2**64, n, dtype=np.uint64, endpoint=False)
    sim = rng.normal(size=n) * 10.0 ** rng.integers(-6, 4, n)
    return np.concatenate([bits.view(np.float64), sim, np.round(sim, 3)])


@pytest.mark.parametrize(("values", "text"), GOLDEN)
def test_the_text_of_a_row_is_the_golden_one(values, text):
    assert repr_row(values) == text
    assert csv_lines([values]) == text.encode()


def test_every_value_is_written_as_repr_and_read_back_bit_for_bit():
    values = np.concatenate([special_values(), random_values(20000, seed=53)])
    values = values[: len(values) // 7 * 7].reshape(-1, 7)
    text = csv_lines(values).decode()
    lines = text.splitlines()
    assert len(lines) == len(values) and text.endswith("\n")
    cells = [c for ln in lines for c in ln.split(",")]
    assert cells == [repr(float(v)) for v in values.ravel().tolist()]
    back = np.array([float(c) for c in cells])
    finite = np.isfinite(values.ravel())
    assert back[finite].view(np.uint64).tolist() == values.ravel()[finite].view(np.uint64).tolist()
    assert np.array_equal(np.isnan(back), np.isnan(values.ravel()))


def test_every_csv_writer_writes_the_same_text(tmp_path):
    values = np.concatenate([special_values()[:1700], random_values(600, seed=5)[:1700]])
    values = values.reshape(-1, 17)
    expected = "".join(repr_row(r) for r in values.tolist())
    assert csv_lines(values).decode() == expected
    table = recorders.Table(recorders.array("d", values.tobytes()), *values.shape)
    assert csv_lines(table).decode() == expected  # the recorders' own tables
    names = [f"c{i}" for i in range(17)]
    rec = CsvRecorder(tmp_path / "r.csv")
    rec.start(names)
    for r in values[:40].tolist():  # one by one, then in a block as the C loop hands them
        rec.row(r)
    block = (ctypes.c_double * values[40:].size)(*values[40:].ravel().tolist())
    rec.rows_block(block, len(values) - 40, 17)
    rec.close()
    assert (tmp_path / "r.csv").read_text() == ",".join(names) + "\n" + expected

    from glider_cosim.sweeps.worker import _csv_text
    from glider_cosim.verify.reference import read_csv, write_csv

    assert _csv_text(["a"] * 17, values).decode() == ",".join(["a"] * 17) + "\n" + expected
    assert _csv_text(["a"], None) == b"a\n"
    write_csv(tmp_path / "ref.csv", names, values)
    _, back = read_csv(tmp_path / "ref.csv")
    finite = np.isfinite(values)
    assert np.array_equal(back[finite], values[finite])


def test_csv_lines_names_a_table_that_is_not_2d():
    with pytest.raises(ValueError, match=r"^csv_lines needs a 2-D table of numbers, got 1 "):
        csv_lines(np.zeros(3))
    assert csv_lines(np.zeros((0, 4))) == b""
    assert csv_lines([[1, 2.5]]) == b"1.0,2.5\n"


def test_a_csv_recorder_keeps_the_rows_it_writes(tmp_path):
    rows = np.random.default_rng(3).normal(size=(300, 4)) * 10.0 ** np.arange(-8, 8, 4)
    rows[5, 1], rows[7, 2] = -0.0, np.inf
    rec = CsvRecorder(tmp_path / "r.csv", keep=ArrayRecorder())
    rec.start(["time", "a", "b", "c"])
    for r in rows[:130]:  # one by one, then a block
        rec.row(list(r))
    block = (ctypes.c_double * rows[130:].size)(*rows[130:].ravel())
    rec.rows_block(block, len(rows) - 130, 4)
    rec.close()
    assert rec.n_rows == 300
    kept = rec.keep.array()
    read = np.loadtxt(tmp_path / "r.csv", delimiter=",", skiprows=1, ndmin=2)
    assert kept.tobytes() == read.tobytes() == rows.tobytes()  # bit for bit


def test_the_rows_before_a_failure_are_written(tmp_path):
    """A run that fails mid-way closes its recorder (``run.py``'s ``finally``): every row
    handed over is in the file, none lost in a buffer."""
    path = tmp_path / "r.csv"
    rec = CsvRecorder(path)
    rec.start(["time", "x"])
    try:
        for k in range(5000):
            if k == 4321:
                raise RuntimeError("an FMU failed")
            rec.row([0.02 * k, math.sin(k)])
    except RuntimeError:
        pass
    finally:
        rec.close()
    lines = path.read_text().splitlines()
    assert len(lines) == 1 + 4321 and lines[-1] == repr_row([0.02 * 4320, math.sin(4320)])[:-1]


def test_a_recorder_closed_before_its_start_leaves_no_file(tmp_path):
    path = tmp_path / "never.csv"  # a run that failed before its first row
    rec = CsvRecorder(path)
    rec.close()
    assert not path.exists()
    rec.close()  # closed: nothing more


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
def test_a_full_disk_is_raised_with_the_path():
    rec = CsvRecorder(Path("/dev/full"))  # every write: ENOSPC, from the kernel
    rec.start(["a", "b"])
    with pytest.raises(OSError, match="No space left on device") as err:
        for _ in range(20000):  # more than the buffer holds
            rec.rows_block((ctypes.c_double * 4)(1.0, 2.0, 3.0, 4.0), 2, 2)
        rec.close()
    assert err.value.errno == 28 and err.value.filename == "/dev/full"
    rec2 = CsvRecorder(Path("/dev/full"))
    rec2.start(["a"])
    rec2.row([1.0])
    with pytest.raises(OSError, match="No space left on device") as err:
        rec2.close()
    assert err.value.errno == 28 and err.value.filename == "/dev/full"
    rec2.close()  # closed: nothing more


def test_a_csv_that_cannot_be_created_is_named_as_open_would(tmp_path):
    path = tmp_path / "no such folder" / "results.csv"
    rec = CsvRecorder(path)
    with pytest.raises(FileNotFoundError) as err:
        rec.start(["a"])
    assert str(path) in str(err.value)


@pytest.mark.parametrize(
    "module, name",
    [("glider_plant", "GliderPlant"), ("glider_observer", "GliderObserver"),
     ("glider_controller", "GliderController")],
)  # fmt: skip
def test_model_description_start_values_read_back_as_the_slaves_own(module, name, tmp_path):
    # pythonfmu writes '%.16g': the observer's theta_meas start (the equilibrium pitch) was
    # -0.3675126816190912 there, one unit in the last place off its -0.36751268161909123
    slave_cls = getattr(importlib.import_module(f"{module}.slave"), name)
    root = slave_cls(instance_name="t", resources=str(tmp_path)).to_xml({})
    starts = {
        sv.get("name"): sv.find("Real").get("start")
        for sv in root.find("ModelVariables")
        if sv.find("Real") is not None and sv.find("Real").get("start") is not None
    }
    spec = {v.name: v.start for v in slave_cls.VARIABLES}
    assert starts and {n: float(t) for n, t in starts.items()} == {n: spec[n] for n in starts}
    assert all(t == repr(float(spec[n])) for n, t in starts.items())
