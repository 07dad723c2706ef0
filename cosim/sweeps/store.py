"""The results file of a sweep, ``sweep.csv``: one row per finished run, safe to kill.

After a kill at any moment (SIGKILL included) the file is still usable:

- it either does not exist or starts with its header: a new or repaired file is written
  to a temporary file beside it and renamed into place;
- a torn last row (the process died while writing it) has no line end; it is dropped
  when the file is opened again, so its run is not counted as done, and is run again;
- every run id appears at most once: a row whose id is already recorded is not written
  again, and a file holding duplicates (or rows without a header, as written by 0.1.0
  after a kill before the first flush) is repaired on opening, keeping the first row.

Every row is one line: line breaks inside values (error messages) become spaces, so a
row is complete exactly when its line end was written.
"""

from __future__ import annotations

import csv
import io
import logging
import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

#: columns every sweep file has (the parameters and metrics vary)
KEY_COLUMN = "run_id"
STATUS_COLUMN = "status"


def _line(values: Sequence[Any]) -> str:
    buf = io.StringIO()
    clean = ["" if v is None else str(v).replace("\r", " ").replace("\n", " ") for v in values]
    csv.writer(buf, lineterminator="\n").writerow(clean)
    return buf.getvalue()


class SweepStore:
    """``sweep.csv`` of a sweep, opened for appending rows.

    Parameters
    ----------
    path : path
        The results file (created with its header if missing or empty).
    columns : sequence of str
        Columns of this sweep's rows; columns of an existing file are kept, new ones are
        appended (the file is rewritten with the union).
    restart : bool
        Forget the rows already in the file.
    """

    def __init__(self, path: str | Path, columns: Sequence[str], restart: bool = False):
        self.path = Path(path)
        self.repaired: list[str] = []  # what opening the file had to fix (for the log)
        self._remove_stale_temporaries()
        if restart:
            self.path.unlink(missing_ok=True)
        header, rows = self._read(list(columns))
        self.columns = header + [c for c in columns if c not in header]
        if self.columns != header:
            self.repaired.append("columns added" if header else "header written")
        self.rows: dict[str, dict[str, str]] = {}
        for r in rows:
            rid = r.get(KEY_COLUMN, "")
            if not rid:
                self.repaired.append("row without run id dropped")
            elif rid in self.rows:
                self.repaired.append(f"duplicate of run {rid} dropped")
            else:
                self.rows[rid] = r
        if self.repaired:
            log.info("%s: %s", self.path, "; ".join(dict.fromkeys(self.repaired)))
            self._rewrite()
        self._f = open(self.path, "a", newline="", encoding="utf-8")  # noqa: SIM115

    # ------------------------------------------------------------------ reading
    def _remove_stale_temporaries(self) -> None:
        if self.path.parent.is_dir():
            for tmp in self.path.parent.glob(f".{self.path.name}.*.tmp"):
                tmp.unlink(missing_ok=True)

    def _read(self, columns: list[str]) -> tuple[list[str], list[dict[str, str]]]:
        """Header and complete rows of the file (``[], []`` if missing or empty)."""
        try:
            data = self.path.read_bytes()
        except FileNotFoundError:
            return [], []
        lines = data.split(b"\n")
        if lines[-1]:  # no line end: the last row is torn
            self.repaired.append("torn last row dropped")
        lines = [ln.decode("utf-8", errors="replace") for ln in lines[:-1] if ln.strip()]
        parsed = [next(csv.reader([ln])) for ln in lines]
        if not parsed:
            return [], []
        if parsed[0] and parsed[0][0] == KEY_COLUMN and STATUS_COLUMN in parsed[0]:
            header, body = parsed[0], parsed[1:]
        else:  # rows without a header: read them with this sweep's columns
            header, body = columns, parsed
            self.repaired.append("rows without a header read with this sweep's columns")
        rows = []
        for fields in body:
            if len(fields) != len(header):
                self.repaired.append("malformed row dropped")
                continue
            rows.append(dict(zip(header, fields, strict=True)))
        return list(header), rows

    # ------------------------------------------------------------------ writing
    def _rewrite(self) -> None:
        """Write header and rows to a temporary file and rename it into place."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        try:
            with open(tmp, "w", newline="", encoding="utf-8") as f:
                f.write(_line(self.columns))
                for r in self.rows.values():
                    f.write(_line([r.get(c, "") for c in self.columns]))
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
        finally:
            tmp.unlink(missing_ok=True)

    def add(self, row: Mapping[str, Any]) -> bool:
        """Append one run's row (buffered until :meth:`flush`); False if its id is
        already recorded (the row is then not written)."""
        rid = str(row[KEY_COLUMN])
        if rid in self.rows:
            return False
        line = _line([row.get(c) for c in self.columns])
        self.rows[rid] = next(csv.DictReader([line], fieldnames=self.columns))
        self._f.write(line)
        return True

    def flush(self) -> None:
        """Hand the rows written so far to the operating system."""
        self._f.flush()

    def close(self) -> None:
        """Flush and close the file."""
        if not self._f.closed:
            self._f.close()

    def __enter__(self) -> SweepStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ queries
    def done(self) -> set[str]:
        """Run ids with a complete row."""
        return set(self.rows)

    def failed(self, run_ids: Iterable[str] | None = None) -> int:
        """Rows whose status is not ``ok`` (among ``run_ids``, default all rows)."""
        ids = self.rows if run_ids is None else set(run_ids) & self.rows.keys()
        return sum(self.rows[i].get(STATUS_COLUMN) != "ok" for i in ids)

    def failed_rows(self, run_ids: Iterable[str], most: int) -> list[dict[str, str]]:
        """The first ``most`` rows among ``run_ids`` (in their order) whose status is not
        ``ok``, as read back (strings)."""
        out = []
        for rid in run_ids:
            row = self.rows.get(rid)
            if row is not None and row.get(STATUS_COLUMN) != "ok":
                out.append(dict(row))
                if len(out) >= most:
                    break
        return out


def write_atomically(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file beside it (a kill leaves the
    old file or the new one, never half of one)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


#: failed runs the console names after a sweep (the rest: in sweep.csv)
SHOWN_FAILURES = 3


def describe_failures(
    failures: Sequence[Mapping[str, Any]], failed_total: int, path: Path,
    param_names: Sequence[str],
) -> list[str]:  # fmt: skip
    """One line per failed run in ``failures`` (rows of ``sweep.csv``: its parameters,
    seed, status and message, shortened to 200 characters), and a last one counting the
    other ``failed_total`` runs that failed; empty if none failed."""
    from ..inputs.text import one_line

    lines = []
    for row in failures:
        params = [f"{k}={_short(row.get(k, ''))}" for k in param_names if k in row]
        if row.get("seed") not in (None, ""):
            params.append(f"seed {row['seed']}")
        message = one_line(row.get("message") or "")
        message = message if len(message) <= 200 else message[:197] + "..."
        what = ", ".join(params) or f"run {row[KEY_COLUMN]}"
        lines.append(f"  failed: {what}: {row.get(STATUS_COLUMN)}: {message}")
    if failed_total > len(failures):
        lines.append(f"  and {failed_total - len(failures)} more failed (each with its status "
                     f"and message in {path})")  # fmt: skip
    return lines


def _short(text: Any) -> str:
    try:
        return f"{float(text):.6g}"
    except (TypeError, ValueError):
        return str(text)


__all__ = ["SHOWN_FAILURES", "SweepStore", "describe_failures", "write_atomically"]
