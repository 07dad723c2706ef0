"""Where a run's rows go: in memory (the API) or streamed to ``results.csv``."""

from __future__ import annotations

import ctypes
import os
import queue
import threading
import weakref
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


class ArrayOnAccess:
    """A dataclass field (``RunResult.data``) set to a :class:`Table` or an array and read
    as a numpy array, made on first access (the run itself needs no numpy)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.slot = "_" + name

    def __get__(self, obj: Any, objtype: type | None = None) -> Any:
        if obj is None:
            raise AttributeError(self.slot[1:])  # no default for the dataclass field
        value = obj.__dict__[self.slot]
        if isinstance(value, Table):
            value = obj.__dict__[self.slot] = value.array()
        return value

    def __set__(self, obj: Any, value: Any) -> None:
        obj.__dict__[self.slot] = value


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
    trajectories, the reference CSVs): formatted by the C helper of
    :mod:`glider_cosim.master.fastloop` (``shortest.c``, about 0.04 us a value) where it is
    available, else in Python, to the same bytes.

    Parameters
    ----------
    data : Table or array_like
        A 2-D table of numbers (one row per line).

    Returns
    -------
    bytes
        The lines, each ending with a newline; empty for no rows.
    """
    from ..master.fastloop import library

    if isinstance(data, Table):  # its doubles as they are: no numpy
        nrows, ncol, table = data.nrows, data.ncol, data
        address = data.address
    else:
        import numpy as np

        table = np.ascontiguousarray(data, dtype=float)
        if table.ndim != 2:
            raise ValueError(
                f"csv_lines needs a 2-D table of numbers, got {table.ndim} dimension(s)"
            )
        nrows, ncol = table.shape
        address = lambda: table.ctypes.data  # noqa: E731
    if nrows == 0 or ncol == 0:
        return b"\n" * nrows if ncol == 0 else b""
    lib = library()
    if lib is None:
        values = table.values.tolist() if isinstance(table, Table) else table.ravel().tolist()
        return "".join(repr_row(values[k : k + ncol]) for k in range(0, len(values), ncol)).encode()
    buf = ctypes.create_string_buffer(nrows * ncol * 25 + 64)
    n = lib.glider_format_rows(ctypes.c_void_p(address()), nrows, ncol, buf, len(buf))
    return ctypes.string_at(buf, n)


class _NativeWriter:
    """csvwriter.c's writer thread: its handle, its file, and whether the recorder has
    started (written the header): the one record of that state, read by
    :meth:`CsvRecorder.close` and by the finalizer that ends the thread if the recorder
    is dropped (it holds this, never the recorder)."""

    def __init__(self, lib: Any, handle: int, path: Path) -> None:
        self.lib, self.handle, self.path = lib, handle, path
        self.started = False

    def end(self) -> int:
        """End the thread (what was handed over written): its errno, or 0. One never
        started leaves no file: the empty one it made is removed."""
        err = self.lib.glider_csv_close(self.handle)
        if not self.started:
            self.path.unlink(missing_ok=True)
        return err


class CsvRecorder:
    """Streams rows to a CSV file (constant memory); ``close`` flushes.

    Every value is written as Python's ``repr`` writes it: the shortest text that reads
    back to the same double (``0.1``, ``1e-05``, ``-0.0``, ``inf``, ``nan``). Where the C
    helper of :mod:`glider_cosim.master.fastloop` is available, rows are collected in
    blocks (of :attr:`BLOCK` rows handed one by one, or the fast loop's blocks) and a
    writer thread formats them (``shortest.c``: the same bytes, about 0.024 us a value
    against 0.25-0.5 us for ``%.17g``) and writes them, in order, while the next block
    steps, on another core; at most :attr:`QUEUED` blocks wait for it. That thread is C's
    own (``csvwriter.c``: handing a block over is a copy, the GIL never changes hands),
    started when the recorder is made, when it creates the file (so that both overlap
    the FMUs' initialisation; closed before :meth:`start`, the recorder removes that
    empty file); where it cannot start (Windows) it is a Python thread calling the C
    formatter with the GIL released, and :meth:`start` opens the file.
    :attr:`THREADED` False: formatted and written in the caller's thread. Without the
    helper, rows are formatted in Python in the caller's thread. An
    error of the writer (a full disk) is raised by the next call that hands rows over,
    else by ``close``.
    """

    BLOCK = 128  # rows handed one by one, formatted at once by the C helper
    QUEUED = 4  # blocks handed to the writer thread and not written yet, at most
    THREADED = True  # False: formatted and written in the caller's thread
    C_THREAD = True  # False: the writer thread is a Python thread (as where C's cannot start)

    def __init__(self, path: Path, keep: ArrayRecorder | None = None) -> None:
        self.path = Path(path)
        #: also handed every row (the run's table for its metrics, without reading the
        #: file back: the same doubles, as the file holds each value exactly)
        self.keep = keep
        self._f = None
        self.n_rows = 0
        self._lib = None
        self._pending = 0
        self._queue: queue.Queue | None = None
        self._writer: threading.Thread | None = None
        self._native: _NativeWriter | None = None  # csvwriter.c's writer, while it runs
        self._closer: weakref.finalize | None = None  # ends it if the recorder is dropped
        self._error: BaseException | None = None  # the writer's, raised once
        self._reported = False
        if self.THREADED and self.C_THREAD:
            self._open_native()

    def _open_native(self) -> None:
        """Start csvwriter.c's thread, which creates the file now: while the FMUs
        initialise, not in the run (0.3-0.6 ms here: the thread's start and ext4's
        create). Where it cannot start, :meth:`start` opens the file."""
        from ..master.fastloop import library

        lib = library(release_gil=True)
        handle = lib.glider_csv_open(os.fsencode(self.path), self.QUEUED) if lib else None
        if handle:
            self._lib, self._native = lib, _NativeWriter(lib, handle, self.path)
            self._closer = weakref.finalize(self, self._native.end)

    def _close_native(self) -> int:
        """End csvwriter.c's thread (:meth:`_NativeWriter.end`): its errno, or 0."""
        err = self._closer() if self._closer is not None else 0
        self._native = self._closer = None
        return err or 0

    def start(self, columns: Sequence[str]) -> None:
        from ..master.fastloop import library

        if self.keep is not None:
            self.keep.start(columns)
        header = (",".join(columns) + "\n").encode()
        self._ncol = len(columns)
        if self._native is not None and columns:  # the C thread made the file: its header
            self._block = (ctypes.c_double * (self.BLOCK * self._ncol))()
            err = self._lib.glider_csv_start(self._native.handle, header, len(header), self._ncol)
            if not err:  # started: its file stays, even if the recorder is dropped
                self._native.started = True
                return
            self._close_native()
            raise self._os_error(err)
        if self._native is not None:  # no columns: the header alone, written here
            self._close_native()
        self._lib = library(release_gil=True) if columns else None
        if self._lib is not None:
            self._block = (ctypes.c_double * (self.BLOCK * self._ncol))()
            self._buf = ctypes.create_string_buffer(self.BLOCK * self._ncol * 25 + 64)
        self._f = open(self.path, "wb", buffering=1 << 16)  # noqa: SIM115
        self._f.write(header)

    def row(self, values: Sequence[float]) -> None:
        if self.keep is not None:
            self.keep.row(list(values))
        if self._lib is None:
            self._f.write(repr_row(values).encode())
        else:
            i = self._pending * self._ncol
            self._block[i : i + self._ncol] = values
            self._pending += 1
            if self._pending == self.BLOCK:
                self._flush()
        self.n_rows += 1

    def rows_block(self, values: Any, nrows: int, ncol: int) -> None:
        """``nrows`` rows of ``ncol`` doubles from a ctypes buffer (the fast loop's, reused
        after the call: copied), after the rows handed one by one before them."""
        if self._lib is None:
            for j in range(nrows):
                self.row(values[j * ncol : (j + 1) * ncol])
            return
        if self.keep is not None:
            self.keep.rows_block(values, nrows, ncol)
        self._flush()
        self._hand_over(values, nrows)
        self.n_rows += nrows

    def _flush(self) -> None:
        if self._pending:
            self._hand_over(self._block, self._pending)
            self._pending = 0

    def _hand_over(self, values: Any, nrows: int) -> None:
        """A copy of ``nrows`` rows of ``values`` to the writer thread (started at the
        first block)."""
        if self._error is not None:
            self._reported = True
            raise self._error
        if not self.THREADED:
            self._write_text(values, nrows)
            return
        if self._native is not None:  # copied by the C thread's glider_csv_put
            err = self._lib.glider_csv_put(self._native.handle, values, nrows)
            if err:
                self._error = self._os_error(err)
                self._reported = True
                raise self._error
            return
        if self._writer is None:
            self._queue = queue.Queue(self.QUEUED)
            self._writer = threading.Thread(target=self._write_blocks, name="csv-writer",
                                            daemon=True)  # fmt: skip
            self._writer.start()
        size = nrows * self._ncol
        copy = (ctypes.c_double * size)()
        ctypes.memmove(copy, values, size * ctypes.sizeof(ctypes.c_double))
        self._queue.put((copy, nrows))

    def _write_blocks(self) -> None:
        """The writer thread: format and write each block handed over, until None."""
        while (item := self._queue.get()) is not None:
            if self._error is None:
                try:
                    self._write_text(*item)
                except BaseException as err:  # noqa: BLE001 - raised again in the caller
                    self._error = err

    def _write_text(self, values: Any, nrows: int) -> None:
        """Format ``nrows`` rows of the ctypes doubles ``values`` in C and write them."""
        need = nrows * self._ncol * 25 + 64  # 25 bytes a value and 64 suffice
        if len(self._buf) < need:
            self._buf = ctypes.create_string_buffer(need)
        n = self._lib.glider_format_rows(values, nrows, self._ncol, self._buf, len(self._buf))
        if n < 0:  # cannot happen, but never lose rows
            rows = values[: nrows * self._ncol]
            text = "".join(repr_row(rows[k : k + self._ncol])
                           for k in range(0, len(rows), self._ncol))  # fmt: skip
            self._f.write(text.encode())
        else:
            self._f.write(memoryview(self._buf)[:n])  # no copy

    def _os_error(self, err: int) -> OSError:
        """The writer's failure ``err`` (an errno) as the OSError a write would raise."""
        return OSError(err, os.strerror(err), str(self.path))

    def close(self) -> None:
        """Write what is left (wait for the writer thread) and close the file.

        Raises
        ------
        OSError
            Writing failed (in the writer thread too).
        """
        if self._f is None and self._native is None:
            return
        try:
            if self._lib is not None and self._error is None:
                self._flush()
        finally:
            if self._native is not None:
                started = self._native.started
                err = self._close_native()  # never started: its empty file removed
                if err and started and self._error is None:
                    self._error = self._os_error(err)
            if self._writer is not None:
                self._queue.put(None)
                self._writer.join()
                self._writer = None
            if self._f is not None:
                self._f.close()
                self._f = None
        if self._error is not None and not self._reported:
            self._reported = True
            raise self._error
