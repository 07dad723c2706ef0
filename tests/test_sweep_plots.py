"""Sweep plots show or count every run (issue 28 point 3)."""

from __future__ import annotations

import csv
from pathlib import Path

from glider_cosim.sweeps import plots
from glider_cosim.sweeps.plots import missing_runs_note, runs_named

COLS = ["run_id", "seed", "controller.K_c", "status", "message", "settling_time_s",
        "control_effort", "estimation_rms_rad"]  # fmt: skip


def write_csv(path: Path, rows: list[dict]) -> Path:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLS)
        w.writeheader()
        for i, r in enumerate(rows):
            w.writerow({"run_id": i, "seed": 0, "status": "ok", "message": "", **r})
    return path


def kc_rows() -> list[dict]:
    settled = {1: 20.0, 2: 12.0, 3: 9.0}
    return [
        {
            "controller.K_c": k,
            "status": "ok",
            "settling_time_s": settled.get(k, ""),
            "control_effort": 0.1 * k,
        }  # fmt: skip
        for k in (1, 2, 3, 4, 6)
    ]


def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_settling_plot_counts_the_runs_that_did_not_settle(tmp_path):
    files = plots.write_plots(write_csv(tmp_path / "sweep.csv", kc_rows()), tmp_path)
    assert [f.name for f in files] == ["settling_vs_effort.png"]
    [(name, spec)] = plots.sweep_specs(_rows(tmp_path / "sweep.csv"))
    assert spec["caption"] == "2 of 5 runs did not settle (K_c = 4, 6)"


def test_failed_runs_are_counted_apart():
    rows = kc_rows()
    rows[0].update(status="error", settling_time_s="", message="K_c = -1 is invalid")
    shown = [r["settling_time_s"] != "" for r in rows]
    assert missing_runs_note(rows, shown, ["controller.K_c"], "did not settle") == (
        "2 of 5 runs did not settle (K_c = 4, 6); 1 of 5 runs failed (K_c = 1)"
    )


def test_every_run_shown_gives_no_note(tmp_path):
    rows = [r for r in kc_rows() if r["settling_time_s"] != ""]
    write_csv(tmp_path / "sweep.csv", rows)
    assert [s["caption"] for _, s in plots.sweep_specs(_rows(tmp_path / "sweep.csv"))] == [""]


def test_the_png_is_drawn_from_the_spec(tmp_path):
    """Issue 49, item 2: a sweep figure is built once, as a spec, and its PNG drawn from it
    (the one the page would draw): the settled runs' points, coloured by K_c."""
    from glider_cosim.figures.mpl import draw_png

    [png] = plots.write_plots(write_csv(tmp_path / "sweep.csv", kc_rows()), tmp_path)
    [(name, spec)] = plots.sweep_specs(_rows(tmp_path / "sweep.csv"))
    [p] = spec["panels"]
    [dots] = p["lines"]
    assert (list(dots["x"]), list(dots["y"]), list(dots["values"])) == (
        [0.1, 0.2, 0.30000000000000004],
        [20.0, 12.0, 9.0],
        [1.0, 2.0, 3.0],
    )
    assert p["colorbar"] == "controller.K_c [1]"
    again = draw_png(spec, tmp_path / "again.png")
    assert name == png.name and png.read_bytes() == again.read_bytes()


def test_runs_are_named_by_every_swept_value():
    rows = [{"a.K_c": "4", "b.V_0": "0.2"}, {"a.K_c": "6.0", "b.V_0": "0.30"}]
    assert runs_named(rows, ["a.K_c", "b.V_0"]) == "K_c = 4, V_0 = 0.2; K_c = 6, V_0 = 0.3"
    assert runs_named(rows, ["a.K_c", "b.K_c"]) == (
        "a.K_c = 4, b.K_c = None; a.K_c = 6, b.K_c = None"
    )
    many = [{"a.K_c": str(k)} for k in range(9)]
    assert runs_named(many, ["a.K_c"]) == "K_c = 0, 1, 2, 3, 4, 5, ..."


def test_runs_are_named_in_the_order_of_their_values():
    rows = [{"controller.K_c": "6"}, {"controller.K_c": "4"}, {"controller.K_c": "10"}]
    assert runs_named(rows, ["controller.K_c"]) == "K_c = 4, 6, 10"
