"""The C row formatter of glider_cosim.master.fastloop writes what Python's repr writes,
whatever the block the recorder formats at once."""

from __future__ import annotations

import math
import random
import struct

import numpy as np
import pytest

from glider_cosim.runner.recorders import CsvRecorder

pytestmark = pytest.mark.integration
SPECIAL = [0.0, -0.0, 1.0, -1.0, math.inf, -math.inf, math.nan, -math.nan, 5e-324, -5e-324,
           2.2250738585072014e-308, 1.7976931348623157e308, 0.1, 1e16, 1e-5, 123456789.0,
           1 / 3, -22.577, 0.59999999999999998]  # fmt: skip


def random_doubles(n: int, seed: int) -> list[float]:
    rng = random.Random(seed)
    out = []
    for _ in range(n):  # any bit pattern, and ordinary magnitudes
        if rng.random() < 0.5:
            out.append(struct.unpack("<d", rng.getrandbits(64).to_bytes(8, "little"))[0])
        else:
            out.append(rng.uniform(-1e3, 1e3) * 10 ** rng.randint(-12, 12))
    return out


@pytest.mark.parametrize("block", [1, 7, 128])
def test_c_formatted_csv_equals_python_formatting(tmp_path, block, monkeypatch):
    ncol = 7
    values = SPECIAL + random_doubles(ncol * 300 - len(SPECIAL), seed=block)
    rows = [tuple(values[i : i + ncol]) for i in range(0, len(values), ncol)]
    monkeypatch.setattr(CsvRecorder, "BLOCK", block)
    rec = CsvRecorder(tmp_path / "c.csv")
    rec.start([f"c{i}" for i in range(ncol)])
    assert rec._lib is not None  # the C path is the one under test
    for r in rows:
        rec.row(r)
    rec.close()
    expected = ",".join(f"c{i}" for i in range(ncol)) + "\n"
    expected += "".join(",".join(map(repr, r)) + "\n" for r in rows)
    assert (tmp_path / "c.csv").read_text() == expected
    back = np.genfromtxt(tmp_path / "c.csv", delimiter=",", skip_header=1)
    finite = np.isfinite(np.array(rows))
    assert np.array_equal(back[finite], np.array(rows)[finite])  # bit for bit
