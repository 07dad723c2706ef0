"""A sweep's folder holds one sweep: another spec is refused, the same one resumes."""

from __future__ import annotations

import json

import pytest

from glider_cosim.sweeps.folder import (
    SweepFolderError,
    check_folder,
    recorded_ids,
    start_folder,
)
from glider_cosim.sweeps.store import SweepStore

COLS = ["run_id", "seed", "controller.K_c", "status"]


def sweep(out, ids, spec, restart=False):
    """What run_sweep does with the folder: record the sweep, then append its rows."""
    start_folder(out, ids, spec, restart)
    with SweepStore(out / "sweep.csv", COLS, restart=restart) as store:
        for i in ids:
            store.add({"run_id": i, "seed": "", "controller.K_c": 1.0, "status": "ok"})


def test_another_sweep_is_refused_with_one_line_and_nothing_written(tmp_path):
    out = tmp_path / "out"
    sweep(out, ["a", "b"], "--param controller.K_c=2,4")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(SweepFolderError) as err:
        start_folder(out, ["a", "c"], "--param controller.K_c=2,6")
    assert str(err.value) == (
        f"{out} holds the results of another sweep (--param controller.K_c=2,4, 2 runs), not "
        "of this one (--param controller.K_c=2,6, 2 runs): give another --out, remove "
        f"{out}, or pass --restart to replace them"
    )
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


@pytest.mark.parametrize("ids", [["a"], ["a", "b", "c"]])
def test_fewer_or_more_runs_are_another_sweep(tmp_path, ids):
    sweep(tmp_path, ["a", "b"], "")
    with pytest.raises(SweepFolderError, match=r"another sweep \(2 runs\)"):
        check_folder(tmp_path, ids)


def test_the_same_sweep_resumes_in_any_order_and_spelling(tmp_path):
    sweep(tmp_path, ["a", "b"], "--param controller.K_c=2,4")
    start_folder(tmp_path, ["b", "a", "a"], "--param controller.K_c=2.0,4")
    assert json.loads((tmp_path / "sweep.json").read_text())["spec"] == (
        "--param controller.K_c=2.0,4"
    )


def test_a_table_without_a_record_is_this_sweeps_when_its_runs_are(tmp_path):
    """sweep.csv written by 0.1.0 (no sweep.json), a torn last row included."""
    (tmp_path / "sweep.csv").write_text(",".join(COLS) + "\na,,2.0,ok\nb,,4.0,ok\nzz,,4")
    assert recorded_ids(tmp_path / "sweep.csv") == {"a", "b"}
    check_folder(tmp_path, ["a", "b", "c"])  # resumes: c is still to run
    with pytest.raises(SweepFolderError, match=r"another sweep \(2 runs, 1 of them not this "):
        check_folder(tmp_path, ["a", "c"], "--param controller.K_c=2,6")


def test_restart_replaces_what_the_earlier_sweep_wrote_and_nothing_else(tmp_path):
    sweep(tmp_path, ["a", "b"], "first")
    traj = tmp_path / "trajectories"
    traj.mkdir()
    for name in ("a.csv", "b.csv", "mine.csv"):
        (traj / name).write_text("t\n")
    for name in ("stability_boundary.png", "sweep.parquet", "notes.txt"):
        (tmp_path / name).write_text("x")
    sweep(tmp_path, ["c"], "second", restart=True)
    assert recorded_ids(tmp_path / "sweep.csv") == {"c"}
    assert sorted(p.name for p in traj.iterdir()) == ["mine.csv"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "notes.txt", "sweep.csv", "sweep.json", "trajectories"]  # fmt: skip
    assert json.loads((tmp_path / "sweep.json").read_text())["spec"] == "second"


def test_a_row_id_is_never_a_path(tmp_path):
    (tmp_path / "keep.csv").write_text("x")
    (tmp_path / "sweep.csv").write_text(",".join(COLS) + "\n../keep,,1,ok\n")
    start_folder(tmp_path, ["c"], restart=True)
    assert (tmp_path / "keep.csv").read_text() == "x"
