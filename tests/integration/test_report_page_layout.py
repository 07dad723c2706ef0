"""report.html reads at 1000-1920 px (issue 45, item 6): in the grids of Figs. 3-4,
Figs. 11-20, Fig. 8 and the region of attraction every plot keeps a readable width, no
legend stands beside a grid's panel, no two tick labels touch, and each row heading
(passivity / P / PI law) stands over its own rows. The page is drawn by the report's
own plotting functions from made-up runs (no FMU run), as ``glider-cosim report``
draws it (each figure from its spec), and laid out by
headless Chromium."""

from __future__ import annotations

import numpy as np
import pytest
from chromium_page import layout
from report_fakes import THETA_E, FakeRun

from glider_cosim.figures.mpl import draw_png
from glider_cosim.figures.pages import write_report_page
from glider_cosim.studies.figures import FIGURES
from glider_cosim.studies.report_plots import figure_spec, sec53_spec
from glider_cosim.studies.roa import CASES, CATEGORIES, RoaMap, roa_spec
from glider_cosim.studies.sec52 import TAILS_DEG, Sec52Run, sec52_spec

pytestmark = [
    pytest.mark.integration,
    pytest.mark.requires_tool("chromium", "chromium-browser"),
]

#: the narrowest plot frame that still shows a curve's shape, px
MIN_FRAME_PX = 200
#: the least gap between two tick labels of an axis, px
MIN_GAP_PX = 2


def _sec53_runs() -> list:
    t = np.linspace(0.0, 90.0, 1801)
    fig = next(f for f in FIGURES if f.key == "fig11-20")
    out = []
    for k, run in enumerate(fig.runs):
        swing = np.exp(-0.05 * (k + 1) * np.clip(t - 31.1, 0, None)) * np.sin(0.8 * t)
        cols = {"plant.theta_g": THETA_E + 0.3 * swing, "plant.theta": THETA_E + 0.35 * swing,
                "controller.delta_cmd": 0.2 * swing}  # fmt: skip
        events = [{"kind": "takeover", "time_s": 31.1, "label": "takeover"}]
        out.append((run, FakeRun(cols, t=t, feedback="observer", metrics={"events": events},
                                 status="ok" if k % 2 else "stopped")))  # fmt: skip
    return out


def _by_key(key: str):
    return next(f for f in FIGURES if f.key == key)


def _runs_of(key: str, cols: tuple[str, ...]) -> list:
    t = np.linspace(0.0, 60.0, 1201)
    return [(run, FakeRun({c: THETA_E + 0.1 * np.exp(-t / (5 + k)) * np.cos(t) for c in cols},
                          t=t)) for k, run in enumerate(_by_key(key).runs)]  # fmt: skip


def _sec52_runs() -> list:
    t = np.linspace(0.0, 4.0, 201)
    out = []
    for k in (1.0, 0.039):
        for tail in TAILS_DEG:
            th = -0.4 + 0.05 * t * tail / 15
            cols = {"plant.theta_meas": th, "plant.theta": th, "observer.theta_hat": th + 0.01}
            out.append(Sec52Run(tail, k, FakeRun(cols, t=t), 2.0, None, None, None, 0.0))
    return out


def _roa_maps() -> list[RoaMap]:
    theta, v = np.radians(np.linspace(-200, 200, 7)), np.linspace(0.05, 1.0, 5)
    cells = np.array([[CATEGORIES[(i + j) % len(CATEGORIES)] for j in range(5)]
                      for i in range(7)], dtype=object)  # fmt: skip
    return [RoaMap(case, theta, v, cells, 60.0, 1.0) for case in CASES]


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    specs = [figure_spec(_by_key("fig2"), _runs_of("fig2", ("plant.theta_g",))),
             figure_spec(_by_key("fig3-4"), _runs_of("fig3-4", ("controller.delta_cmd",
                                                                "plant.theta_g"))),
             sec53_spec(_by_key("fig11-20"), _sec53_runs()),
             sec52_spec(_sec52_runs()), roa_spec(_roa_maps())]  # fmt: skip
    for spec, name in zip(specs, ("fig2", "fig3-4", "fig11-20", "fig8", "roa"), strict=True):
        draw_png(spec, out / f"{name}.png")  # each spec's PNG; the page drawn from them
    write_report_page(out, specs, {"How this report was made": {"command": "test"}})
    return out / "report.html"


_LAID_OUT: dict[int, dict] = {}


def _layout(page, width: int) -> dict:
    """The page laid out at ``width`` px (once per width)."""
    if width not in _LAID_OUT:
        _LAID_OUT[width] = layout(page, width)
    return _LAID_OUT[width]


def _figures(found: dict) -> dict[int, list[dict]]:
    by: dict[int, list[dict]] = {}
    for p in found["plots"]:
        by.setdefault(p["figure"], []).append(p)
    return by


@pytest.mark.parametrize("width", [1000, 1400, 1920])
def test_every_plot_is_wide_enough_with_its_legend_off_the_grid(page, width):
    found = _layout(page, width)
    by = _figures(found)
    assert sorted(by) == [0, 1, 2, 3, 4], "a figure drew no plot"
    for fig, plots in by.items():
        columns = len({round(p["left"]) for p in plots})
        for p in plots:
            assert p["width"] >= MIN_FRAME_PX, (fig, p["title"], p["width"])
            if columns > 1:
                assert not p["legend_beside"], (fig, p["title"], "a legend beside a grid panel")
    assert len({round(p["left"]) for p in by[2]}) == 3  # Figs. 11-20: three columns


@pytest.mark.parametrize("width", [1000, 1920])
def test_no_two_tick_labels_touch(page, width):
    for p in _layout(page, width)["plots"]:
        for axis in ("x", "y"):
            boxes = p[axis]
            assert len(boxes) >= 3, (p["title"], axis, "fewer than three tick labels")
            for (_, hi), (lo, _) in zip(boxes, boxes[1:], strict=False):
                assert lo - hi >= MIN_GAP_PX, (p["figure"], p["title"], axis, boxes)


def test_row_headings_stand_over_their_rows(page):
    found = _layout(page, 1400)
    block = found["blocks"][2]  # Figs. 11-20
    plots = _figures(found)[2]
    heads = [c for c in block if c["tag"] == "h3"]
    assert [h["text"] for h in heads] == ["passivity law", "P law", "PI law"]
    for k, h in enumerate(heads):
        nxt = block[block.index(h) + 1]
        below = [p for p in plots if nxt["top"] <= p["top"] < nxt["bottom"]]
        assert len(below) == 6, (h["text"], len(below))  # three runs, angle and tail rows
        assert h["bottom"] <= min(p["top"] for p in below)
        if k:  # under the rows of the heading before it
            before = block[block.index(h) - 1]
            assert before["bottom"] <= h["top"]
    (key,) = [c for c in block if c["cls"] == "glider-legend"]  # one legend, under the grid
    assert key["top"] >= max(p["bottom"] for p in plots)
    headings = [h.split("</h2>")[0] for h in page.read_text().split("<h2>")[1:]]
    (title,) = [h for h in headings if h.startswith("Figs. 11-20")]
    assert "law" not in title  # the row headings are not stacked under the title
