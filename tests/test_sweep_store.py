"""``sweep.csv`` after a kill at any moment: header, torn rows, duplicates, failures."""

from __future__ import annotations

import csv

import pytest

from glider_cosim.sweeps.store import SweepStore

COLS = ["run_id", "seed", "controller.K_c", "status", "message", "control_effort"]


def row(i: int, status: str = "ok", message: str = "") -> dict:
    return {"run_id": f"r{i}", "seed": "", "controller.K_c": float(i), "status": status,
            "message": message, "control_effort": 0.1 * i}  # fmt: skip


def table(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_the_header_is_there_before_the_first_row(tmp_path):
    path = tmp_path / "sweep.csv"
    store = SweepStore(path, COLS)  # not closed: as after a kill
    assert path.read_text() == ",".join(COLS) + "\n"
    store.close()


def test_an_empty_file_gets_its_header(tmp_path):
    path = tmp_path / "sweep.csv"
    path.write_text("")
    with SweepStore(path, COLS) as store:
        assert store.done() == set()
        store.add(row(1))
    assert [r["run_id"] for r in table(path)] == ["r1"]


def full_file(path, n=5):
    with SweepStore(path, COLS) as store:
        for i in range(n):
            store.add(row(i, "error" if i == 3 else "ok", "boom,\nsecond line" if i == 3 else ""))
    return path.read_bytes()


def test_a_kill_at_any_byte_leaves_a_usable_file(tmp_path):
    """Rows are appended, so a kill leaves a prefix of the complete file: every prefix
    opens with the header, counts only complete rows, and completes without duplicates."""
    data = full_file(tmp_path / "full.csv")
    header_len = len(",".join(COLS)) + 1
    ends = [i + 1 for i, b in enumerate(data) if b == ord("\n")]
    assert len(ends) == 6  # header + 5 rows, the message's line break removed
    for cut in range(header_len, len(data) + 1):
        path = tmp_path / f"cut{cut}.csv"
        path.write_bytes(data[:cut])
        complete = sum(e <= cut for e in ends) - 1
        with SweepStore(path, COLS) as store:
            assert store.done() == {f"r{i}" for i in range(complete)}
            for i in range(5):  # the resumed sweep adds what is missing
                if f"r{i}" not in store.done():
                    store.add(row(i, "error" if i == 3 else "ok"))
        rows = table(path)
        assert [r["run_id"] for r in rows] == [f"r{i}" for i in range(5)], cut
        assert path.read_bytes().endswith(b"\n")
        path.unlink()


def test_a_torn_last_row_is_not_counted_and_is_rewritten(tmp_path):
    path = tmp_path / "sweep.csv"
    data = full_file(path, 3)
    path.write_bytes(data + b"r3,,3.0,o")  # killed while writing run r3
    with SweepStore(path, COLS) as store:
        assert store.done() == {"r0", "r1", "r2"}
        assert "torn last row dropped" in store.repaired
        assert store.add(row(3))
    rows = table(path)
    assert [r["run_id"] for r in rows] == ["r0", "r1", "r2", "r3"]
    assert rows[-1]["status"] == "ok" and rows[-1]["control_effort"] == "0.30000000000000004"


def test_no_duplicate_run_ids(tmp_path):
    path = tmp_path / "sweep.csv"
    with SweepStore(path, COLS) as store:
        assert store.add(row(1))
        assert not store.add(row(1, "error"))  # a second result of the same run
    assert [r["status"] for r in table(path)] == ["ok"]


def test_rows_without_header_and_duplicates_from_0_1_0_are_repaired(tmp_path):
    """0.1.0 killed before its first flush left an empty file; later runs appended rows
    without a header and redid (duplicated) them."""
    path = tmp_path / "sweep.csv"
    body = "".join(",".join(str(row(i)[c]) for c in COLS) + "\n" for i in (1, 2, 1, 2, 3))
    path.write_text(body)
    with SweepStore(path, COLS) as store:
        assert store.done() == {"r1", "r2", "r3"}
    rows = table(path)
    assert list(rows[0]) == COLS
    assert [r["run_id"] for r in rows] == ["r1", "r2", "r3"]


def test_failures_recorded_earlier_are_counted(tmp_path):
    path = tmp_path / "sweep.csv"
    with SweepStore(path, COLS) as store:
        store.add(row(1, "error", "K_c = -1.0 is invalid"))
        store.add(row(2))
    with SweepStore(path, COLS) as store:  # the resumed sweep
        store.add(row(3, "stopped"))
        assert store.failed() == 2
        assert store.failed(["r1", "r2", "r3", "r3"]) == 2
        assert store.failed(["r2", "r9"]) == 0


def test_new_columns_are_added_and_stale_temporaries_removed(tmp_path):
    path = tmp_path / "sweep.csv"
    with SweepStore(path, COLS) as store:
        store.add(row(1))
    stale = tmp_path / ".sweep.csv.4242.tmp"  # a kill during a repair
    stale.write_text("partial")
    with SweepStore(path, [*COLS, "plant.K_L"]) as store:
        store.add({**row(2), "plant.K_L": 310.0})
    assert not stale.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep.csv"]
    rows = table(path)
    assert list(rows[0]) == [*COLS, "plant.K_L"]
    assert [(r["run_id"], r["plant.K_L"]) for r in rows] == [("r1", ""), ("r2", "310.0")]


def test_restart_forgets_the_rows(tmp_path):
    path = tmp_path / "sweep.csv"
    with SweepStore(path, COLS) as store:
        store.add(row(1))
    with SweepStore(path, COLS, restart=True) as store:
        assert store.done() == set()
    assert table(path) == []


@pytest.mark.parametrize("message", ["line one\nline two", "a\r\nb", 'comma, "quote"'])
def test_every_row_is_one_line(tmp_path, message):
    path = tmp_path / "sweep.csv"
    with SweepStore(path, COLS) as store:
        store.add(row(1, "error", message))
    assert path.read_text().count("\n") == 2
    assert table(path)[0]["message"] == message.replace("\r", " ").replace("\n", " ")
