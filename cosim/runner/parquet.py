"""``results.parquet``: the run's rows in a binary columnar file pandas and polars read.

The CSV recorder's text costs about 0.5-1 us a row here (17 values as ``repr``, in C; it
was 4 us with ``%.17g``), against about 1 us a step for a native run without it. This
recorder keeps the values as they are (float64, exact) and writes them in row groups of
:attr:`ParquetRecorder.GROUP` rows through pyarrow: constant memory, and a failure
mid-run leaves every row computed so far in the file once the recorder is closed
(``simulate`` closes it on every path).
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np


class ParquetFormatError(ValueError):
    """pyarrow, which writes Parquet, is not installed."""


def require_pyarrow() -> Any:
    """pyarrow, or a one-line :class:`ParquetFormatError` naming the extra to install."""
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError:
        raise ParquetFormatError(
            "--format parquet needs pyarrow: pip install 'glider-cosim[parquet]' (or --format csv)"
        ) from None
    return pyarrow


class ParquetRecorder:
    """Streams rows to a Parquet file in row groups; ``close`` writes the last one."""

    GROUP = 4096  # rows per row group

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.n_rows = 0
        self._pa = require_pyarrow()
        self._writer: Any = None
        self._buf: np.ndarray | None = None
        self._pending = 0

    def start(self, columns: Sequence[str]) -> None:
        pa = self._pa
        self.columns = list(columns)
        self._schema = pa.schema([(c, pa.float64()) for c in self.columns])
        self._writer = pa.parquet.ParquetWriter(str(self.path), self._schema)
        self._buf = np.empty((self.GROUP, len(self.columns)))

    def row(self, values: Sequence[float]) -> None:
        self._buf[self._pending] = values
        self._pending += 1
        self.n_rows += 1
        if self._pending == self.GROUP:
            self._flush()

    def rows_block(self, values: Any, nrows: int, ncol: int) -> None:
        """``nrows`` rows of ``ncol`` doubles from a ctypes buffer (the fast loop's)."""
        block = np.ctypeslib.as_array(ctypes.cast(values, ctypes.POINTER(ctypes.c_double)),
                                      shape=(nrows * ncol,)).reshape(nrows, ncol)  # fmt: skip
        j = 0
        while j < nrows:
            take = min(self.GROUP - self._pending, nrows - j)
            self._buf[self._pending : self._pending + take] = block[j : j + take]
            self._pending += take
            self.n_rows += take
            j += take
            if self._pending == self.GROUP:
                self._flush()

    def _flush(self) -> None:
        if not self._pending or self._writer is None:
            return
        rows = self._buf[: self._pending]
        arrays = [self._pa.array(rows[:, i]) for i in range(rows.shape[1])]
        self._writer.write_table(self._pa.Table.from_arrays(arrays, schema=self._schema))
        self._pending = 0

    def close(self) -> None:
        if self._writer is not None:
            self._flush()
            self._writer.close()
            self._writer = None

    def read(self) -> np.ndarray:
        """The rows written, as an array (for the metrics)."""
        table = self._pa.parquet.read_table(str(self.path))
        if table.num_rows == 0:
            return np.empty((0, len(self.columns)))
        return np.column_stack([table.column(c).to_numpy() for c in self.columns])
