"""The report's and a run's figures (issue 28 point 5): titles on one line, every exit
from the axes marked, legends out of the data, every mark in a legend, the measured
pitch not listed when it is the true one, the equilibrium speed on speed.png."""

from __future__ import annotations

import numpy as np
import pytest
from report_fakes import THETA_E, FakeRun

from glider_cosim.figures import plots as run_plots
from glider_cosim.figures.mpl import draw
from glider_cosim.studies.figures import FIGURES, Figure, Run
from glider_cosim.studies.report_plots import figure_spec, plot_figure, plot_sec53, sec53_spec


def _clipped(ax):
    return [ln for ln in ax.get_lines() if ln.get_gid() == "clipped"]


def test_fig5_6_title_one_line_every_exit_marked_legend_outside(tmp_path):
    t = np.linspace(0, 10, 501)
    calm = THETA_E + 0.05 * np.exp(-t)  # the bounded run sets the axes
    wild = THETA_E + np.sin(2 * np.pi * 0.3 * t)  # leaves them above and below: 6 exits
    results = [
        (Run("K_c = 10", "x"), FakeRun({c: calm for c in ("plant.theta_meas",
                                        "observer.theta_g_hat", "plant.theta_g")})),
        (Run("K_c = 2", "x"), FakeRun({c: wild for c in ("plant.theta_meas",
                                       "observer.theta_g_hat", "plant.theta_g")},
                                      status="stopped", metrics={"outcome": "stopped"})),
    ]  # fmt: skip
    fig = FIGURES[2]
    assert fig.key == "fig5-6"
    png = plot_figure(fig, results, tmp_path)  # fig5-6.png: the spec drawn
    f = draw(figure_spec(fig, results))
    f.savefig(tmp_path / "again.png", dpi=100)
    assert png.read_bytes() == (tmp_path / "again.png").read_bytes()
    assert "\n" not in f.get_suptitle()
    panels = [ax for ax in f.get_axes()]
    assert all(ax.get_legend() is None for ax in panels)  # no legend over the curves
    (legend,) = f.legends
    labels = [x.get_text() for x in legend.get_texts()]
    assert labels == ["K_c = 10", "K_c = 2 (stopped at 10.0 s)", "equilibrium",
                      "leaves the axes (clipped there)",
                      "the run stops (V or V_hat stalls or diverges)"]  # fmt: skip
    side = np.sign(np.round(wild - THETA_E, 9))  # outside the calm run's narrow range
    exits = int(np.sum((side != 0) & (side != np.r_[0, side[:-1]])))
    assert exits == 6
    for ax in panels:
        assert len(_clipped(ax)) == exits


def test_fig11_20_legend_names_the_stop_line_of_the_tail_panel(tmp_path):
    t = np.linspace(0, 10, 501)
    cols = {"plant.theta_g": THETA_E + 0 * t, "plant.theta": THETA_E + 0 * t,
            "controller.delta_cmd": 0.1 * np.sin(t)}  # fmt: skip
    stopped = FakeRun(cols, status="stopped", feedback="observer",
                      metrics={"outcome": "stopped"}, message="plant: fmi2Error")  # fmt: skip
    fig = Figure("fig11-20", "Figs. 11-20", (), FIGURES[3].panels, by_group=True)
    runs = [(Run("a", "x", group="g"), FakeRun(cols, feedback="observer")),
            (Run("b", "x", group="g"), stopped)]  # fmt: skip
    png = plot_sec53(fig, runs, tmp_path)  # fig11-20.png: the spec drawn
    f = draw(sec53_spec(fig, runs))
    f.savefig(tmp_path / "again.png", dpi=90)
    assert png.read_bytes() == (tmp_path / "again.png").read_bytes()
    labels = [x.get_text() for x in f.legends[0].get_texts()]
    assert "stop" in labels and "stop (tail panel)" in labels and "tail command" in labels
    assert "cross and red line: the run stops" in f.get_suptitle()


def _run_result(noise_std: float, meas_offset: float):
    t = np.linspace(0, 10, 501)
    theta = -0.4 + 0.01 * np.sin(t)
    cols = {"plant.theta_g": theta, "plant.theta": theta, "plant.theta_meas": theta + meas_offset,
            "observer.theta_hat": theta + 0.001, "controller.delta_cmd": 0 * t,
            "plant.V": 0.2 + 0 * t, "observer.V_hat": 0.21 + 0 * t}  # fmt: skip
    r = FakeRun(cols, metrics={"V_e_m_s": 0.237})
    r.scenario.parameters["plant"]["noise_std"] = noise_std
    return r


def _labels(panel):
    return [ln["name"] for ln in panel["lines"] if ln["legend"]]


def _by_title(specs):
    return {s["title"].split(" (")[0]: s for s in specs}


def test_pitch_at_noise_0_lists_no_measured_series_and_speed_marks_the_equilibrium(tmp_path):
    specs = []
    run_plots.write_plots(_run_result(0.0, 0.0), tmp_path, keep=specs)
    by_name = _by_title(specs)
    top, below = by_name["Pitch"]["panels"]
    assert _labels(top) == ["true = measured (noise std 0 deg)", "estimate"]
    assert _labels(below) == ["estimate - true"]
    speed = by_name["Speed"]["panels"][0]
    assert _labels(speed) == ["true", "estimate", "equilibrium"]
    (eq,) = [ln for ln in speed["lines"] if ln["name"] == "equilibrium"]
    assert eq["y"][0] == eq["y"][1] == pytest.approx(0.237)
    assert list(eq["x"]) == speed["xlim"]  # across the panel


def test_pitch_with_noise_lists_the_measured_samples(tmp_path):
    specs = []
    run_plots.write_plots(_run_result(0.1, 0.05), tmp_path, keep=specs)
    top, below = _by_title(specs)["Pitch"]["panels"]
    assert _labels(top)[0].startswith("measured (samples, noise std 5.7 deg)")
    assert _labels(below) == ["measured - true", "estimate - true"]
    assert top["lines"][0]["marker"] == "." and not top["lines"][0]["lines"]


def test_fig8_has_one_legend_under_the_panels_and_the_stop_in_the_title(tmp_path):
    from glider_cosim.figures.mpl import draw
    from glider_cosim.studies.sec52 import TAILS_DEG, Sec52Run, plot_sec52, sec52_spec

    t = np.linspace(0, 4, 201)
    th = -0.4 + 0.05 * t
    cols = {"plant.theta_meas": th, "plant.theta": th, "observer.theta_hat": th + 0.01}
    runs = [Sec52Run(tail, 1.0, FakeRun(cols, status="stopped" if tail == TAILS_DEG[0] else "ok"),
                     2.0, None, None, None, 0.0) for tail in TAILS_DEG]  # fmt: skip
    spec = sec52_spec(runs)
    png = plot_sec52(runs, tmp_path)  # fig8.png: the spec drawn
    f = draw(spec)
    f.savefig(tmp_path / "again.png", dpi=100)
    assert png.read_bytes() == (tmp_path / "again.png").read_bytes()
    assert all(ax.get_legend() is None for ax in f.get_axes())
    (legend,) = f.legends
    assert [x.get_text() for x in legend.get_texts()] == [
        "measured", "true", "estimated", "observer starts", "the run stops"]  # fmt: skip
    assert f.get_axes()[0].get_title().endswith(": stops at 4.00 s")


def test_fig11_20_spec_puts_each_law_over_its_rows_not_in_the_title(tmp_path):
    t = np.linspace(0, 10, 501)
    cols = {"plant.theta_g": THETA_E + 0 * t, "plant.theta": THETA_E + 0 * t,
            "controller.delta_cmd": 0.1 * np.sin(t)}  # fmt: skip
    runs = [(Run(f"{g} {k}", "x", group=g), FakeRun(cols, feedback="observer"))
            for g in ("passivity law", "P law") for k in (1, 2)]  # fmt: skip
    spec = sec53_spec(Figure("fig11-20", "Figs. 11-20", (), FIGURES[3].panels, by_group=True),
                      runs)  # fmt: skip
    assert "law" not in spec["title"]
    rows = {p["row"]: p["heading"] for p in spec["panels"]}
    assert rows == {0: "passivity law", 1: "passivity law", 2: "P law", 3: "P law"}
    f = draw(spec)  # each heading over its rows, in the PNG as on the page
    assert [sub.get_suptitle() for sub in f.subfigs] == ["passivity law", "P law"]


def test_fig11_20_tail_axis_is_linear_with_evenly_spaced_ticks(tmp_path):
    t = np.linspace(0, 10, 501)
    cols = {"plant.theta_g": THETA_E + 0 * t, "plant.theta": THETA_E + 0 * t,
            "controller.delta_cmd": 0.1 * np.sin(t)}  # fmt: skip
    fig = Figure("fig11-20", "Figs. 11-20", (), FIGURES[3].panels, by_group=True)
    f = draw(sec53_spec(fig, [(Run("a", "x", group="g"), FakeRun(cols, feedback="observer"))]))
    (tail,) = [ax for ax in f.get_axes() if ax.get_ylabel() == "tail cmd [deg]"]
    assert tail.get_yscale() == "linear"
    ticks = list(tail.get_yticks())
    assert ticks == [-90, -45, 0, 45, 90] and len(set(np.diff(ticks))) == 1
    assert tail.get_ylim() == (-100.0, 100.0)


def _roa_maps():
    from glider_cosim.studies.roa import CASES, CATEGORIES, RoaMap

    cells = [[CATEGORIES[(i + j) % len(CATEGORIES)] for j in range(3)] for i in range(2)]
    cells = np.array([*cells, ["settled", "unknown", "settled"]], dtype=object)
    return [RoaMap(c, np.radians([-30.0, 0.0, 30.0]), np.array([0.1, 0.2, 0.3]), cells, 60.0, 1.0)
            for c in CASES[:2]]  # fmt: skip


def test_roa_is_one_spec_drawn_to_png_and_to_the_page(tmp_path):
    """Issue 49, item 2: the region-of-attraction figure is built once, as a spec; roa.png
    and report.html are drawn from it (no matplotlib figure read back)."""
    from glider_cosim.figures.mpl import draw_png
    from glider_cosim.figures.pages import write_report_page
    from glider_cosim.studies.roa import plot_roa, roa_spec

    spec = roa_spec(_roa_maps())
    assert [(p["row"], p["col"]) for p in spec["panels"]] == [(0, 0), (0, 1)]
    image = spec["panels"][0]["images"][0]
    assert image["value"].tolist() == [["settled", "not settled", "limit cycle"],
                                       ["not settled", "limit cycle", "diverging"],
                                       ["settled", "", "settled"]]  # fmt: skip
    assert image["rgba"][2, 1].tolist() == [0, 0, 0, 0]  # an unknown outcome: no colour
    assert image["rgba"][0, 0].tolist() == [0x2C, 0xA0, 0x2C, 255]  # settled: tab:green
    assert (image["x"], image["dw"]) == pytest.approx((0.05, 0.3))
    assert [n["text"] for n in spec["notes"]][-1] == "stopped (stall)"
    png = plot_roa(_roa_maps(), tmp_path)
    assert png.read_bytes() == draw_png(spec, tmp_path / "again.png").read_bytes()
    page = write_report_page(tmp_path, [spec], {"made": {"command": "test"}})["page"]
    text = page.read_text()
    assert text.count("class='glider-figure'") == 1 and '"limit cycle"' in text
    assert spec["title"].startswith("Region of attraction") and spec["title"] in text


def test_the_step_study_is_one_spec_drawn_to_png_and_to_the_page(tmp_path):
    """Issue 49, item 2: communication_step.png and its figure in report.html come from one
    spec: the glide angle at 50 Hz, 200 Hz and in continuous time over the differences."""
    from glider_cosim.figures.mpl import draw_png
    from glider_cosim.figures.pages import write_report_page
    from glider_cosim.studies.steps import plot_steps, steps_spec

    t = np.linspace(0.0, 10.0, 101)
    study = {"traces": {"t": t, "50 Hz": t * 1e-3, "200 Hz": t * 2e-3, "continuous": 0 * t}}
    spec = steps_spec(study)
    top, below = spec["panels"]
    assert [ln["name"] for ln in top["lines"]] == ["50 Hz", "200 Hz", "continuous"]
    assert [ln["name"] for ln in below["lines"]] == ["50 Hz - continuous", "200 Hz - continuous"]
    assert below["lines"][1]["y"][-1] == pytest.approx(2e-2 * 180 / np.pi)
    png = plot_steps(study, tmp_path)
    assert png.read_bytes() == draw_png(spec, tmp_path / "again.png").read_bytes()
    page = write_report_page(tmp_path, [spec], {"made": {"command": "test"}})["page"]
    assert "50 Hz - continuous" in page.read_text()
