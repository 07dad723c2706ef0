"""``sweep``'s last line (how many runs settled, which values did not) and its ``--out``
check, up front as every command's (issue 54)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from glider_cosim.cli import main as cli_main
from glider_cosim.sweeps import sweep
from glider_cosim.sweeps.sweep import outcome_summary

HEADER = "run_id,controller.K_c,seed,status,message,settling_time_s,outcome\n"


def _table(tmp_path: Path, lines: list[str]) -> Path:
    path = tmp_path / "sweep.csv"
    path.write_text(HEADER + "".join(f"{x}\n" for x in lines))
    return path


def test_the_summary_counts_the_settled_runs_and_names_the_others(tmp_path):
    path = _table(tmp_path, [
        "a,10.0,,ok,,11.18,settled",
        "b,2.0,3,ok,,,limit cycle",
        "c,0.05,,stopped,observer stalled,,",
        "d,-1.0,,error,K_c = -1 is invalid,,",
        "e,12.0,,ok,,12.0,settled",
    ])  # fmt: skip
    assert outcome_summary(path, ["controller.K_c"]) == (
        "sweep: 2 of 5 runs settled; not settled: controller.K_c=2 seed 3 (limit cycle), "
        "controller.K_c=0.05 (stopped), controller.K_c=-1 (error)"
    )


def test_every_run_settled_and_a_long_list_is_cut(tmp_path):
    path = _table(tmp_path, ["a,10.0,,ok,,11.18,settled"])
    assert outcome_summary(path, ["controller.K_c"]) == "sweep: 1 of 1 runs settled"
    path = _table(tmp_path, [f"r{k},{k}.5,,ok,,,diverged" for k in range(11)])
    line = outcome_summary(path, ["controller.K_c"], shown=3)
    assert line == (
        "sweep: 0 of 11 runs settled; not settled: controller.K_c=0.5 (diverged), "
        "controller.K_c=1.5 (diverged), controller.K_c=2.5 (diverged) and 8 more (in sweep.csv)"
    )


@pytest.fixture
def no_dask(monkeypatch):
    """Dask and the builds must not start: each raises if reached."""

    def reached(*a, **k):
        raise AssertionError("reached past the up-front checks")

    monkeypatch.setattr(sweep, "make_client", reached)
    monkeypatch.setattr("glider_cosim.fmus.folders.build_all", reached)


def test_an_unwritable_out_is_refused_up_front(tmp_path, monkeypatch, capsys, no_dask):
    ro = tmp_path / "ro"
    ro.mkdir()
    real = os.access
    # root may write anywhere but a read-only file system: that one answers as such
    monkeypatch.setattr(os, "access", lambda p, m, **k: Path(p) != ro and real(p, m, **k))
    code = cli_main(["sweep", "--param", "controller.K_c=6,8", "--out", str(ro / "s")])
    assert code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"glider-cosim sweep: error: --out '{ro / 's'}': '{ro}' is not writable"
    ]


def test_an_out_that_is_a_file_is_refused_up_front(tmp_path, capsys, no_dask):
    (tmp_path / "f").write_text("x")
    code = cli_main(["sweep", "--param", "controller.K_c=6,8", "--out", str(tmp_path / "f")])
    assert code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"glider-cosim sweep: error: --out '{tmp_path / 'f'}': exists and is not a folder: "
        "expected a folder"
    ]
