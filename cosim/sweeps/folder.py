"""Whose results a sweep's folder holds: ``sweep.json`` names the sweep that writes
``sweep.csv`` beside it, so that a sweep of another spec is refused, not mixed in.

A sweep's spec is its list of runs (their ids: scenario, stop time, parameters, seed;
:func:`~glider_cosim.sweeps.spec.run_id`): the same list resumes, another one is refused
before any run with one line naming the folder, the sweep it holds and how to go on.
``--restart`` replaces the folder's sweep with this one (its table, plots, Parquet file,
the trajectories of its runs, and ``sweep.json``). A ``sweep.csv`` without
``sweep.json`` (written by 0.1.0) is this sweep's when every run id in it is one of
this sweep's.
"""

from __future__ import annotations

import csv
import hashlib
import json
import re
from collections.abc import Iterable, Sequence
from pathlib import Path

from .store import KEY_COLUMN, write_atomically

#: the record of the sweep a folder holds
SPEC_FILE = "sweep.json"
#: the results table
TABLE_FILE = "sweep.csv"
#: what else a sweep writes in its folder (replaced by ``--restart``)
OUTPUT_FILES = ("sweep.parquet", "settling_vs_effort.png", "stability_boundary.png",
                "estimation_vs_noise.png")  # fmt: skip


class SweepFolderError(ValueError):
    """The results folder holds another sweep's results (the message names it)."""


def runs_digest(ids: Iterable[str]) -> str:
    """SHA-256 of a sweep's run ids (order and repeats do not matter)."""
    return hashlib.sha256("\n".join(sorted(set(ids))).encode()).hexdigest()


def _record(out: Path) -> dict | None:
    try:
        record = json.loads((out / SPEC_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and "runs_sha256" in record else None


def recorded_ids(table: Path) -> set[str]:
    """The run ids of the complete rows of ``table`` (empty if it is missing)."""
    try:
        data = table.read_bytes()
    except FileNotFoundError:
        return set()
    lines = data.split(b"\n")[:-1]  # a torn last row (no line end) is not a run
    ids = set()
    for row in csv.reader(ln.decode("utf-8", errors="replace") for ln in lines if ln.strip()):
        if row and row[0] and row[0] != KEY_COLUMN:
            ids.add(row[0])
    return ids


def _runs(n: int) -> str:
    return f"{n} run" + ("" if n == 1 else "s")


def check_folder(out: Path, ids: Sequence[str], spec: str = "", restart: bool = False) -> None:
    """Refuse ``out`` if it holds another sweep's results.

    Parameters
    ----------
    out : Path
        The results folder.
    ids : sequence of str
        This sweep's run ids.
    spec : str
        This sweep's spec as the user wrote it (for the message), e.g.
        ``--param controller.K_c=2:30:15``.
    restart : bool
        ``--restart``: whatever the folder holds is replaced, nothing is refused.

    Raises
    ------
    SweepFolderError
        ``OUT holds the results of another sweep (...), not of this one (...): ...``.
    """
    table = out / TABLE_FILE
    if restart or not table.is_file():
        return
    record = _record(out)
    mine = set(ids)
    if record is not None:
        if record["runs_sha256"] == runs_digest(mine):
            return
        theirs = ", ".join(x for x in (record.get("spec"), _runs(record.get("runs", 0))) if x)
    else:
        held = recorded_ids(table)
        if held <= mine:
            return  # written before sweep.json was: the rows are this sweep's
        theirs = f"{_runs(len(held))}, {len(held - mine)} of them not this sweep's"
    ours = ", ".join(x for x in (spec, _runs(len(mine))) if x)
    raise SweepFolderError(
        f"{out} holds the results of another sweep ({theirs}), not of this one ({ours}): "
        f"give another --out, remove {out}, or pass --restart to replace them"
    )


def start_folder(out: Path, ids: Sequence[str], spec: str = "", restart: bool = False) -> None:
    """Check ``out`` (:func:`check_folder`), then record this sweep in ``sweep.json``.

    With ``restart``, what the folder's earlier sweep wrote goes first: its table, the
    files of :data:`OUTPUT_FILES`, and ``trajectories/<run_id>.csv`` of its runs.
    """
    check_folder(out, ids, spec, restart)
    out.mkdir(parents=True, exist_ok=True)
    if restart:
        for rid in recorded_ids(out / TABLE_FILE):
            if re.fullmatch(r"[\w-]+", rid):  # a name, never a path
                (out / "trajectories" / f"{rid}.csv").unlink(missing_ok=True)
        for name in (TABLE_FILE, *OUTPUT_FILES):
            (out / name).unlink(missing_ok=True)
    record = {"spec": spec, "runs": len(set(ids)), "runs_sha256": runs_digest(ids)}
    if _record(out) != record:
        write_atomically(out / SPEC_FILE, (json.dumps(record, indent=1) + "\n").encode())


__all__ = ["OUTPUT_FILES", "SPEC_FILE", "SweepFolderError", "check_folder", "recorded_ids",
           "runs_digest", "start_folder"]  # fmt: skip
