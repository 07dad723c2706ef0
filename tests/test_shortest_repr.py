"""The CSV text of every double is Python's repr: the C formatter (cosim/master/shortest.c,
through the fast loop's helper) and the Python writers, bit for bit on reading back."""

from __future__ import annotations

import ctypes
import importlib
import importlib.util
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from glider_cosim.master import fastloop
from glider_cosim.runner import recorders
from glider_cosim.runner.recorders import CsvRecorder, csv_lines, repr_row

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def lib():
    lib = fastloop.library()
    if lib is None:
        pytest.skip("no C compiler for the fast loop's helper")
    return lib


def c_lines(lib, values: np.ndarray, ncol: int = 1) -> list[str]:
    """``values`` formatted by glider_format_rows in rows of ``ncol``, one text a value."""
    values = np.ascontiguousarray(values, dtype=float)
    buf = ctypes.create_string_buffer(values.size * 25 + 64)
    n = lib.glider_format_rows(ctypes.c_void_p(values.ctypes.data), values.size // ncol, ncol,
                               buf, len(buf))  # fmt: skip
    assert n > 0
    text = ctypes.string_at(buf, n).decode()
    assert text.endswith("\n") and text.count("\n") == values.size // ncol
    return text.replace("\n", ",")[:-1].split(",")


def from_bits(bits: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(bits, dtype=np.uint64).view(np.float64)


def special_values() -> np.ndarray:
    """Zeros, the extremes, subnormals, every power of two and its neighbours, the powers
    of ten and theirs, the fixed/scientific boundaries of repr, short decimals."""
    xs = [0.0, 5e-324, 1e-323, 2.2250738585072009e-308, 2.2250738585072014e-308,
          1.7976931348623157e308, math.inf, 0.1, 0.2, 0.3, 0.30000000000000004, 1 / 3, 2 / 3,
          math.pi, math.e, 123.0, 100.0, 1e-4, 9.999999999999999e-05, 1e16, 1e15,
          9999999999999998.0, 1e16 - 2, 1e22, 1e23, 9007199254740993.0, 2.5, 0.5, 1.5,
          5e-324 * 3, 123456789012345678.0, 1.2345678901234567e-300, 4.35e-321]  # fmt: skip
    xs += [2.0**q for q in range(-1074, 1024)]
    xs += [10.0**e for e in range(-323, 309)]
    xs += [float(f"1e{e}") for e in range(-323, 309)]
    xs += [k / 10**d for d in range(1, 6) for k in range(1, 1000, 7)]
    xs += [float(i) for i in range(-1000, 1000)]
    arr = np.array(xs)
    with np.errstate(over="ignore"):  # nextafter(max, inf) is inf
        arr = np.concatenate([arr, np.nextafter(arr, np.inf), np.nextafter(arr, -np.inf)])
    arr = arr[~np.isnan(arr)]
    subnormal = from_bits(np.arange(1, 5000, dtype=np.uint64) * 7919)
    top = from_bits((np.uint64(0x7FE) << np.uint64(52)) + np.arange(0, 3000, dtype=np.uint64))
    arr = np.concatenate([arr, subnormal, top, [math.nan]])
    return np.concatenate([arr, -arr])


def random_values(n: int, seed: int) -> np.ndarray:
    """``n`` doubles of uniformly random bit patterns (every exponent and sign, NaNs too)."""
    rng = np.random.default_rng(seed)
    return from_bits(rng.integers(0, 2**64, size=n, dtype=np.uint64, endpoint=False))


def assert_repr_and_bits(values: np.ndarray, texts: list[str]) -> None:
    assert len(texts) == len(values)
    py = values.tolist()
    bad = [(r, t) for r, t in zip(map(repr, py), texts, strict=True) if r != t]
    assert bad[:5] == []
    back = np.array([float(t) for t in texts])
    finite = ~np.isnan(values)
    assert np.isnan(back[~finite]).all()
    assert back[finite].view(np.uint64).tolist() == values[finite].view(np.uint64).tolist()


def test_a_million_random_doubles_are_written_as_repr_and_read_back_bit_for_bit(lib):
    values = random_values(1_000_000, seed=31)
    assert_repr_and_bits(values, c_lines(lib, values))


def test_values_of_every_fixed_notation_layout_are_written_as_repr(lib):
    """Random bit patterns are mostly written in scientific notation; a simulation's
    values are not: 300,000 doubles log-uniform over 1e-6 .. 1e17 (both signs, every
    layout: 0.000ddd, the point among the digits, integers with ".0", and both sides of
    repr's 1e-4 and 1e16 switches), and as many rounded to 1-6 decimals (short texts,
    trailing zeros stripped)."""
    rng = np.random.default_rng(7)
    wide = np.exp(rng.uniform(np.log(1e-6), np.log(1e17), 300_000))
    wide *= rng.choice([-1.0, 1.0], wide.size)
    scale = 10.0 ** rng.integers(1, 7, 300_000)
    short = np.round(rng.uniform(-1000, 1000, 300_000) * scale) / scale
    values = np.concatenate([wide, short])
    assert_repr_and_bits(values, c_lines(lib, values))


def test_special_values_are_written_as_repr_and_read_back_bit_for_bit(lib):
    values = special_values()
    assert_repr_and_bits(values, c_lines(lib, values))
    assert c_lines(lib, np.array([0.1, 1e-5, -0.0, math.inf, -math.inf, -math.nan, 123.0, 1e16,
                                  5e-324, 1.7976931348623157e308]))  == [
        "0.1", "1e-05", "-0.0", "inf", "-inf", "nan", "123.0", "1e+16", "5e-324",
        "1.7976931348623157e+308",
    ]  # fmt: skip


def test_rows_of_many_columns_are_comma_separated_lines(lib):
    values = np.concatenate([special_values(), random_values(7 * 4000, seed=1)])
    values = values[: len(values) // 17 * 17]
    assert c_lines(lib, values, ncol=17) == [repr(v) for v in values.tolist()]
    text = csv_lines(values.reshape(-1, 17)).decode()
    assert text.splitlines()[0] == ",".join(repr(v) for v in values[:17].tolist())


def test_the_portable_128_bit_multiply_and_bit_counts_give_the_same_text(tmp_path):
    from glider_fmi import toolchain

    try:
        cmd = [
            *toolchain.host_command(),
            *fastloop.FLAGS,
            "-DGLIDER_PORTABLE_MUL128",
            "-DGLIDER_PORTABLE_BITS",
        ]
    except OSError:
        pytest.skip("no C compiler")
    out = tmp_path / f"shortest{'.dll' if sys.platform == 'win32' else '.so'}"
    toolchain.run([*cmd, str(fastloop.SOURCES[1]), "-o", str(out)], "shortest.c")
    portable = ctypes.CDLL(str(out))
    values = np.concatenate([special_values(), random_values(50_000, seed=2)])
    buf = ctypes.create_string_buffer(64)
    texts = []
    for v in values.tolist():
        n = portable.glider_repr(ctypes.c_double(v), buf)
        texts.append(buf.raw[:n].decode())
    assert_repr_and_bits(values, texts)


def test_the_power_of_ten_table_is_the_generators_output():
    spec = importlib.util.spec_from_file_location("gen", ROOT / "tools" / "gen_pow10_table.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    assert (ROOT / "cosim" / "master" / "shortest_pow10.h").read_text() == gen.text()


def test_every_csv_writer_writes_the_same_text(tmp_path, lib, monkeypatch):
    values = np.concatenate([special_values()[:1700], random_values(1700, seed=5)]).reshape(-1, 17)
    expected = "".join(repr_row(r) for r in values.tolist())
    assert csv_lines(values).decode() == expected

    def recorded(name: str) -> str:
        rec = CsvRecorder(tmp_path / name)
        rec.start([f"c{i}" for i in range(17)])
        # csvwriter.c's thread where it can start (here), else a Python one or none
        assert (rec._native is not None) == (CsvRecorder.THREADED and CsvRecorder.C_THREAD)
        for r in values.tolist():
            rec.row(r)
        rec.close()
        head, _, body = (tmp_path / name).read_text().partition("\n")
        assert head == ",".join(f"c{i}" for i in range(17))
        return body

    assert recorded("c.csv") == expected
    monkeypatch.setattr(CsvRecorder, "C_THREAD", False)  # a Python writer thread
    assert recorded("pythread.csv") == expected
    monkeypatch.setattr(CsvRecorder, "THREADED", False)  # formatted in this thread
    assert recorded("sync.csv") == expected
    monkeypatch.setattr(fastloop, "library", lambda **kw: None)  # the Python path
    assert recorded("py.csv") == expected
    assert csv_lines(values).decode() == expected

    from glider_cosim.sweeps.sweep import _csv_text
    from glider_cosim.verify.reference import read_csv, write_csv

    assert _csv_text(["a"] * 17, values).decode() == ",".join(["a"] * 17) + "\n" + expected
    write_csv(tmp_path / "ref.csv", [f"c{i}" for i in range(17)], values)
    cols, back = read_csv(tmp_path / "ref.csv")
    finite = np.isfinite(values)
    assert np.array_equal(back[finite], values[finite])


def test_csv_lines_names_a_table_that_is_not_2d():
    with pytest.raises(ValueError, match=r"^csv_lines needs a 2-D table of numbers, got 1 "):
        csv_lines(np.zeros(3))
    assert csv_lines(np.zeros((0, 4))) == b""
    assert recorders.csv_lines([[1, 2.5]]) == b"1.0,2.5\n"


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


class _FullDisk:
    def write(self, data) -> int:
        raise OSError(28, "No space left on device")

    def close(self) -> None:
        pass


def test_a_write_error_of_the_writer_thread_is_raised_once(tmp_path, lib, monkeypatch):
    monkeypatch.setattr(CsvRecorder, "C_THREAD", False)  # the Python thread (Windows)
    rec = CsvRecorder(tmp_path / "full.csv")
    rec.start(["a", "b"])
    rec._f.close()
    rec._f = _FullDisk()
    block = (ctypes.c_double * 4)(1.0, 2.0, 3.0, 4.0)
    rec.rows_block(block, 2, 2)  # handed over: the writer thread fails on it
    with pytest.raises(OSError, match="No space left on device"):
        rec.close()
    rec.close()  # closed: nothing raised twice


def test_rows_handed_after_a_writer_error_raise_it(tmp_path, lib, monkeypatch):
    monkeypatch.setattr(CsvRecorder, "C_THREAD", False)  # the Python thread (Windows)
    rec = CsvRecorder(tmp_path / "full.csv")
    rec.start(["a"])
    rec._f.close()
    rec._f = _FullDisk()
    rec.rows_block((ctypes.c_double * 1)(1.0), 1, 1)
    for _ in range(1000):  # until the writer thread has taken the block and failed on it
        if rec._error is not None:
            break
        time.sleep(0.01)
    with pytest.raises(OSError, match="No space left on device"):
        rec.rows_block((ctypes.c_double * 1)(2.0), 1, 1)
    rec.close()  # already raised: not again


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_a_full_disk_under_the_c_writer_thread_is_raised_once_with_the_path(lib):
    rec = CsvRecorder(Path("/dev/full"))  # every write: ENOSPC, from the kernel
    rec.start(["a", "b"])
    assert rec._native is not None
    with pytest.raises(OSError, match=r"^\[Errno 28\] No space left on device: '/dev/full'$"):
        for _ in range(100_000):  # until the thread has failed (at the header) and says so
            rec.rows_block((ctypes.c_double * 4)(1.0, 2.0, 3.0, 4.0), 2, 2)
            time.sleep(0.001)
    rec.close()  # already raised: not again
    rec = CsvRecorder(Path("/dev/full"))
    rec.start(["a"])
    rec.row([1.0])
    with pytest.raises(OSError, match="No space left on device") as err:
        rec.close()
    assert err.value.errno == 28 and err.value.filename == "/dev/full"
    rec.close()


def test_a_csv_the_c_writer_thread_cannot_create_is_named_as_open_would(tmp_path, lib):
    path = tmp_path / "no such folder" / "results.csv"
    rec = CsvRecorder(path)
    rec.start(["a"])  # the file is created by the thread: its failure comes with the rows
    assert rec._native is not None
    rec.row([1.0])
    with pytest.raises(FileNotFoundError) as err:
        rec.close()
    with pytest.raises(FileNotFoundError) as opened:
        open(path, "wb")  # noqa: SIM115 - the message Python's open gives
    assert str(err.value) == str(opened.value)
    assert not path.parent.exists()


def test_the_c_writer_thread_creates_the_file_when_the_recorder_is_made(tmp_path, lib):
    # before the run knows its columns (while the FMUs initialise): the thread's start and
    # ext4's create are not in the run; the header comes with start
    path = tmp_path / "early.csv"
    rec = CsvRecorder(path)
    assert rec._native is not None
    for _ in range(1000):  # the thread creates it: soon, not at once
        if path.exists():
            break
        time.sleep(0.005)
    assert path.read_bytes() == b""
    rec.start(["a", "b"])
    rec.row([0.1, -0.0])
    rec.close()
    assert path.read_text() == "a,b\n0.1,-0.0\n"


def test_a_recorder_closed_before_its_start_leaves_no_file(tmp_path, lib):
    path = tmp_path / "never.csv"  # a run that failed before its first row
    rec = CsvRecorder(path)
    rec.close()
    assert not path.exists()
    rec.close()  # closed: nothing more


@pytest.mark.skipif(not Path("/proc/self/fd").exists(), reason="no /proc/self/fd")
def test_a_recorder_dropped_without_close_ends_its_thread_and_file(tmp_path, lib):
    import gc

    before = len(os.listdir("/proc/self/fd"))
    threads = len(os.listdir("/proc/self/task"))
    for i in range(5):
        CsvRecorder(tmp_path / f"dropped{i}.csv")  # no close: the finalizer closes it
    rec = CsvRecorder(tmp_path / "started.csv")
    rec.start(["a"])
    rec.rows_block((ctypes.c_double * 1)(1.5), 1, 1)  # handed over: written by the thread
    del rec
    gc.collect()
    assert len(os.listdir("/proc/self/fd")) == before
    assert len(os.listdir("/proc/self/task")) == threads
    # never started: no file (as a run that failed before its first row); started: what
    # was handed over is written (rows still collected in Python are not: close is needed)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["started.csv"]
    assert (tmp_path / "started.csv").read_text() == "a\n1.5\n"


def test_the_started_state_is_kept_once(tmp_path, lib):
    """Whether the recorder has started (its file stays) is one record, the C writer's,
    which the finalizer reads too: no flag of the recorder's beside a copy in the
    finalizer's arguments."""
    rec = CsvRecorder(tmp_path / "once.csv")
    native = rec._native
    assert native is not None and native.started is False
    _, end, args, _ = rec._closer.peek()
    assert end.__self__ is native and args == ()  # reads the record when it runs
    rec.start(["a"])
    assert native.started is True and rec._closer.peek()[1].__self__ is native
    assert not hasattr(rec, "_started")
    rec.close()
    assert (tmp_path / "once.csv").read_text() == "a\n"
