"""The run's PNGs drawn with Pillow (issue 31, ``figures/raster.py``, ``figures/strokes.py``):
ticks and their labels, dashes, where lines, translucent lines, inverted axes and
legends land in the pixels, the PNG's size and text chunks, and the errors."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from glider_cosim.figures import plots, raster, strokes

RED = "#ff0000"


@pytest.mark.parametrize(
    ("lo", "hi", "nbins", "want"),
    [
        (-3.0, 63.0, 9, [0, 10, 20, 30, 40, 50, 60]),
        (-36.0, -16.5, 9, [-36, -34, -32, -30, -28, -26, -24, -22, -20, -18]),
        (-36.0, -16.5, 7, [-35, -32.5, -30, -27.5, -25, -22.5, -20, -17.5]),
        (0.0, 1.0, 4, [0, 0.25, 0.5, 0.75, 1.0]),
        (0.0012, 0.0049, 3, [0.002, 0.003, 0.004]),
    ],
)
def test_ticks_are_round_steps_within_the_limits(lo, hi, nbins, want):
    ticks = raster.nice_ticks(lo, hi, nbins)
    assert ticks == pytest.approx(want)
    assert len(ticks) <= nbins + 1 and ticks[0] >= lo and ticks[-1] <= hi


@pytest.mark.parametrize(
    "lim", [(1.0, 1.0), (2.0, 1.0), (0.0, float("nan")), (0, float("inf")), (-1e308, 1e308)]
)
def test_bad_limits_are_a_render_error(lim):
    with pytest.raises(raster.RenderError, match=r"axis limits \[.*\]: expected finite, "
                       r"increasing limits"):  # fmt: skip
        raster.nice_ticks(*lim, 5)


def test_tick_labels_share_their_decimals_and_use_a_minus_sign():
    m = "\N{MINUS SIGN}"
    assert raster.tick_labels(np.array([-35, -32.5, -30])) == [f"{m}35.0", f"{m}32.5", f"{m}30.0"]
    assert raster.tick_labels(np.array([0, 10, 20])) == ["0", "10", "20"]
    assert raster.tick_labels(np.array([-1e-17, 0.1, 0.2])) == ["0.0", "0.1", "0.2"]  # no -0.0
    assert raster.tick_labels(np.array([0, 2e-4, 4e-4])) == ["0.0e+00", f"2.0e{m}04", f"4.0e{m}04"]
    assert raster.tick_labels(np.array([2e5, 4e5])) == ["2.0e+05", "4.0e+05"]


def test_dashes_cover_their_share_of_the_line():
    pts = np.array([[0.0, 0.0], [100.0, 0.0]])
    on = strokes._dashes(pts, (3.0, 1.0))
    assert len(on) == 25
    assert sum(p[-1, 0] - p[0, 0] for p in on) == pytest.approx(75.0)
    assert on[1][0, 0] == pytest.approx(4.0)  # the second dash after a 1 px gap
    assert strokes._dashes(pts[:1], (3.0, 1.0))[0].shape == (1, 2)  # a point stays a point


def _spec(lines, ylim=(0.0, 1.0), inverted=False, kind="single"):
    p = {"title": "t", "xlabel": "x", "ylabel": "y", "xlim": [0.0, 1.0], "ylim": list(ylim),
         "inverted": inverted, "lines": lines, "legend_pt": 7.0}  # fmt: skip
    return {"title": "t", "suptitle": "s", "panels": [p], "size_in": plots.SIZES[kind],
            "margins": plots.SINGLE_MARGINS, "height_ratios": [1.0]}  # fmt: skip


def _box(spec):
    """The figure and its panel's box in the PNG's pixels."""
    _, (box,) = raster.layout(spec)
    return raster.render(spec), [v / strokes.SCALE for v in box]


def _rows_of(im, rgb, tol=40):
    a = np.asarray(im, dtype=int)
    hit = np.all(np.abs(a - np.array(rgb)) <= tol, axis=2)
    return np.flatnonzero(hit.any(axis=1)), np.flatnonzero(hit.any(axis=0))


def test_a_line_lands_where_its_value_is():
    line = plots.line([0.0, 1.0], [0.25, 0.25], color=RED, width=1.5)
    im, (x0, y0, x1, y1) = _box(_spec([line]))
    rows, cols = _rows_of(im, (255, 0, 0))
    assert rows.mean() == pytest.approx(y1 - 0.25 * (y1 - y0), abs=1.0)
    assert cols.min() <= x0 + 1 and cols.max() >= x1 - 2  # across the panel, not beyond
    assert cols.min() >= x0 - 1 and cols.max() <= x1 + 1


def test_an_inverted_axis_puts_small_values_on_top():
    line = plots.line([0.0, 1.0], [0.25, 0.25], color=RED, width=1.5)
    im, (_, y0, _, y1) = _box(_spec([line], inverted=True))
    rows, _ = _rows_of(im, (255, 0, 0))
    assert rows.mean() == pytest.approx(y0 + 0.25 * (y1 - y0), abs=1.0)


def test_a_translucent_line_is_its_colour_over_white_once():
    x = np.linspace(0, 1, 400)
    line = plots.line(x, 0.5 + 0 * x, color="#000000", width=8.0, alpha=0.3)
    im, (x0, y0, x1, y1) = _box(_spec([line]))
    mid = np.asarray(im, dtype=int)[round((y0 + y1) / 2), round((x0 + x1) / 2)]
    assert mid == pytest.approx([round(255 * 0.7)] * 3, abs=2)


def test_points_off_the_chart_and_gaps_do_not_break_the_drawing():
    y = np.array([0.1, np.nan, 0.5, 1e300, -np.inf, 0.9])
    line = plots.line(np.linspace(0, 1, 6), y, color=RED)
    dots = plots.line([0.2, 0.4], [0.2, np.nan], color=RED, marker="o")
    im, _ = _box(_spec([line, dots]))
    assert _rows_of(im, (255, 0, 0))[0].size  # what is finite is drawn


def test_the_legend_goes_where_the_data_is_not():
    x = np.linspace(0, 1, 200)
    high = plots.line(x, 0.9 + 0 * x, "high", color=RED)  # along the top: not "upper right"
    spec = _spec([high])
    box = (0.0, 0.0, 1000.0, 500.0)
    pts = [np.column_stack([x * 1000, 0 * x + 40])]
    lx, ly, w, h = raster._legend_box([high], box, 7.0, pts)
    assert ly > 40 and ly + h <= 500  # below the line, inside the panel
    assert lx + w <= 1000 and lx >= 0
    lx, ly, _, _ = raster._legend_box([high], box, 7.0, [])
    assert (lx, ly) == pytest.approx(
        (1000 - raster.pt_px(3.5) - w, raster.pt_px(3.5))
    )  # upper right
    assert raster.render(spec).size == (770, 396)


def test_the_png_has_its_size_text_chunks_and_no_part_file(tmp_path):
    line = plots.line([0.0, 1.0], [0.2, 0.8], "rise", color=RED)
    meta = {plots.META_EVENTS: "[]", plots.META_SETTINGS: "scenario x; no overrides"}
    path = raster.render_png(_spec([line], kind="pair") | {"height_ratios": [1.0]},
                             tmp_path / "a.png", meta)  # fmt: skip
    with Image.open(path) as im:
        assert im.size == (770, 572) and im.mode == "RGB"
        assert plots.read_png_record(path) == {"events": [], "settings": "scenario x; no overrides"}
    again = raster.render_png(_spec([line], kind="pair") | {"height_ratios": [1.0]},
                              tmp_path / "b.png", meta)  # fmt: skip
    assert again.read_bytes() == path.read_bytes()  # the same spec, the same bytes
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "b.png"]
    with pytest.raises(OSError):
        raster.render_png(_spec([line]), tmp_path / "missing" / "c.png", meta)
    assert not list(tmp_path.rglob("*.part"))


def test_specs_that_cannot_be_drawn_say_why():
    with pytest.raises(raster.RenderError, match=r"figure 't': no panels; expected at least one"):
        raster.render(_spec([]) | {"panels": []})
    with pytest.raises(raster.RenderError, match=r"2 height ratios for 1 panels"):
        raster.render(_spec([]) | {"height_ratios": [1.0, 2.0]})
    bad = plots.line([0.0, 1.0], [0.0, 1.0], color="red")
    with pytest.raises(raster.RenderError, match=r"colour 'red': expected #rrggbb"):
        raster.render(_spec([bad]))


def test_without_matplotlibs_font_pillows_own_is_used(monkeypatch):
    import importlib.util

    raster.font.cache_clear()
    monkeypatch.setattr(importlib.util, "find_spec", lambda name: None)
    try:
        f = raster.font(10.0)
        assert "DejaVu" not in " ".join(f.getname())
        assert raster.render(_spec([plots.line([0, 1], [0, 1], "a")])).size == (770, 396)
    finally:
        raster.font.cache_clear()


def test_the_png_reads_back_pixel_for_pixel_with_its_resolution_and_text():
    import io

    line = plots.line([0.0, 1.0], [0.2, 0.8], "rise", color=RED)
    image = raster.render(_spec([line]))
    meta = {plots.META_EVENTS: '[{"label": "\N{GREEK SMALL LETTER THETA} = 1"}]', "k": ""}
    data = raster.png_bytes(image, meta)
    with Image.open(io.BytesIO(data)) as im:
        im.verify()  # every chunk's CRC
    with Image.open(io.BytesIO(data)) as im:
        assert np.array_equal(np.asarray(im.convert("RGB")), np.asarray(image))
        assert im.info["dpi"] == pytest.approx((110, 110), abs=0.01)
        assert im.text == meta
    with pytest.raises(raster.RenderError, match=r"image mode 'L': expected 'RGB'"):
        raster.png_bytes(image.convert("L"), {})


def test_a_legend_lets_what_it_covers_show_faintly():
    """As matplotlib's (framealpha 0.8): a line under the legend stays visible."""
    im = Image.new("RGB", (400, 200), (255, 0, 0))
    entry = plots.line([0.0, 1.0], [0.0, 1.0], "a", color="#0000ff")
    raster._draw_legend(im, [entry], (100.0, 50.0, 200.0, 60.0), 7.0)
    a = np.asarray(im, dtype=int)
    assert list(a[100, 280]) == pytest.approx([255, 204, 204], abs=1)  # inside, no ink
    assert list(a[10, 10]) == [255, 0, 0]  # outside: untouched
    assert (np.abs(a[50:111, 100:301] - [0, 0, 255]).sum(axis=2) < 60).any()  # its handle
