"""Where a run's rows go: in memory (the API) or streamed to ``results.csv``."""

from __future__ import annotations

import ctypes
from array import array
from collections.abc import Sequence
from pathlib import Path
from typing import Any


class Table:
    """A run's rows of doubles without numpy: row-major, ``ncol`` values a row (time
    first), as the recorders keep them; :meth:`array` makes the numpy array.

    Parameters
    ----------
    values : array.array of 'd'
        The rows' values, row after row (not copied: the table owns them).
    nrows, ncol : int
        Rows, and values in a row.
    """

    __slots__ = ("values", "nrows", "ncol")

    def __init__(self, values: array, nrows: int, ncol: int) -> None:
        self.values, self.nrows, self.ncol = values, nrows, ncol

    def __len__(self) -> int:
        return self.nrows

    def value(self, row: int, col: int) -> float:
        """One value (``row`` may be negative, as an index)."""
        return self.values[(row % self.nrows) * self.ncol + col]

    def address(self) -> int:
        """Where the values are in memory (for the C helper; valid while the table is
        alive and not grown)."""
        return self.values.buffer_info()[0]

    def array(self) -> Any:
        """The rows as a 2-D numpy array of float64, ``(nrows, ncol)`` (a copy)."""
        import numpy as np

        if not self.nrows or not self.ncol:
            return np.empty((self.nrows, self.ncol))
        return np.frombuffer(self.values, dtype=float).reshape(self.nrows, self.ncol).copy()


class ArrayRecorder:
    """Keeps rows in memory (for the API): their doubles in an ``array.array``, no numpy
    until :meth:`array`."""

    def __init__(self) -> None:
        self.columns: list[str] = []
        self._values = array("d")
        self._nrows = 0

    def start(self, columns: Sequence[str]) -> None:
        self.columns = list(columns)

    def row(self, values: Sequence[float]) -> None:
        self._values.extend(values)
        self._nrows += 1

    def rows_block(self, values: Any, nrows: int, ncol: int) -> None:
        """``nrows`` rows of ``ncol`` doubles from a ctypes buffer (copied)."""
        self._values.frombytes(ctypes.string_at(values, nrows * ncol * 8))
        self._nrows += nrows

    def __len__(self) -> int:
        return self._nrows

    def close(self) -> None:
        pass

    def table(self, n_columns: int | None = None) -> Table:
        """The rows as a :class:`Table` (a copy of the values), ``n_columns`` wide when
        no columns were started."""
        n = len(self.columns) if self.columns else (n_columns or 0)
        if self._nrows and len(self._values) != self._nrows * n:
            raise ValueError(
                f"{self._nrows} rows of {len(self._values)} values in all: expected "
                f"{n} values a row"
            )
        return Table(array("d", self._values), self._nrows, n)

    def array(self, n_columns: int | None = None) -> Any:
        """The rows as a 2-D numpy array of float64 (a copy)."""
        return self.table(n_columns).array()


def repr_row(values: Sequence[float]) -> str:
    """One CSV line (with its newline), every value as ``repr(float(v))``.

    Parameters
    ----------
    values : sequence of float
        The row's values (any unit: the text is exact).

    Returns
    -------
    str
        The shortest text of each value that reads back to the same double, e.g.
        ``0.1,1e-05,-0.0,inf,nan``.
    """
    return ",".join([repr(float(v)) for v in values]) + "\n"


def csv_lines(data: Any) -> bytes:
    """Rows of doubles as CSV lines, each value as Python's ``repr`` writes it.

    The text every CSV writer of the project uses (``results.csv``, ``sweep.csv``'s
    trajectories, the reference CSVs), by :func:`repr_row`.

    Parameters
    ----------
    data : Table or array_like
        A 2-D table of numbers (one row per line).

    Returns
    -------
    bytes
        The lines, each ending with a newline; empty for no rows.

    Raises
    ------
    ValueError
        ``data`` is not a 2-D table.
    """
    if isinstance(data, Table):
        ncol, values = data.ncol, data.values.tolist()
        rows = [values[k : k + ncol] for k in range(0, len(values), ncol)] if ncol else []
        rows += [[]] * (data.nrows - len(rows))
    else:
        import numpy as np

        table = np.asarray(data, dtype=float)
        if table.ndim != 2:
            raise ValueError(
                f"csv_lines needs a 2-D table of numbers, got {table.ndim} dimension(s)"
            )
        rows = table.tolist()
    return "".join([repr_row(r) for r in rows]).encode()


class CsvRecorder:
    """Streams rows to a CSV file (constant memory); ``close`` flushes.

    Every value is written as Python's ``repr`` writes it (:func:`repr_row`): the
    shortest text that reads back to the same double (``0.1``, ``1e-05``, ``-0.0``,
    ``inf``, ``nan``). The file is created by :meth:`start` (a recorder closed before it
    leaves none) and written through a buffer of :attr:`BUFFER` bytes; :meth:`close`
    writes what the buffer holds, so a run that fails keeps every row handed over
    before the failure. An error of a write (a full disk) is raised by the call that
    made it, or by ``close``, as an :class:`OSError` naming the file.

    Parameters
    ----------
    path : Path
        The CSV file (replaced if it exists).
    keep : ArrayRecorder, optional
        Also handed every row (the run's table for its metrics, without reading the
        file back: the same doubles, as the file holds each value exactly).
    """

    BUFFER = 1 << 16  # bytes written at once

    def __init__(self, path: Path, keep: ArrayRecorder | None = None) -> None:
        self.path = Path(path)
        self.keep = keep
        self._f: Any = None
        self.n_rows = 0

    def start(self, columns: Sequence[str]) -> None:
        """Create the file and write its header: the column names."""
        if self.keep is not None:
            self.keep.start(columns)
        self._f = open(self.path, "w", encoding="utf-8", newline="", buffering=self.BUFFER)  # noqa: SIM115
        self._f.write(",".join(columns) + "\n")

    def row(self, values: Sequence[float]) -> None:
        """Write one row (time first)."""
        if self.keep is not None:
            self.keep.row(values)
        self._write(repr_row(values))
        self.n_rows += 1

    def rows_block(self, values: Any, nrows: int, ncol: int) -> None:
        """``nrows`` rows of ``ncol`` doubles from a ctypes buffer (the fast loop's, reused
        after the call: copied)."""
        block = array("d", ctypes.string_at(values, nrows * ncol * 8)).tolist()
        if self.keep is not None:
            self.keep.rows_block(values, nrows, ncol)
        self._write("".join([repr_row(block[k : k + ncol]) for k in range(0, nrows * ncol, ncol)]))
        self.n_rows += nrows

    def _write(self, text: str) -> None:
        try:
            self._f.write(text)
        except OSError as err:
            raise self._named(err) from None

    def _named(self, err: OSError) -> OSError:
        """``err`` (a write's, which names no file) naming the file."""
        return OSError(err.errno, err.strerror, str(self.path)) if err.filename is None else err

    def close(self) -> None:
        """Write what is left and close the file (once; again: nothing).

        Raises
        ------
        OSError
            Writing failed.
        """
        f, self._f = self._f, None
        if f is not None:
            try:
                f.close()
            except OSError as err:
                raise self._named(err) from None
