"""A figure spec drawn with matplotlib (``figures/mpl.py``, issue 49 item 2): what the
spec says is where the PNG shows it."""

from __future__ import annotations

import numpy as np
from PIL import Image

from glider_cosim.figures.mpl import draw_png
from glider_cosim.figures.spec import line, panel, sheet


def _where(png, rgb: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(Image.open(png).convert("RGB")).astype(int)
    ys, xs = np.nonzero(np.abs(a - np.array(rgb)).sum(axis=2) < 30)
    return xs / a.shape[1], ys / a.shape[0]


def test_panels_go_to_their_cells_and_the_caption_under_them(tmp_path):
    red = panel([line([0, 1], [0, 1], "up [m]", color="tab:purple", width=3.0)],
                title="a", xlabel="t [s]", ylabel="z [m]", row=0)  # fmt: skip
    green = panel([line([0, 1, 2], [1, 0, 1], marker="o", color="tab:green", size=9.0)],
                  title="b", xlabel="t [s]", ylabel="z [m]", row=1, grid=0.3)  # fmt: skip
    green["col"] = 1
    png = draw_png(sheet([red, green], (6.0, 5.0), "a note"), tmp_path / "grid.png")
    assert Image.open(png).size == (600, 500)
    x, y = _where(png, (0x94, 0x67, 0xBD))  # tab:purple: the line, top left
    assert len(x) > 100 and x.max() < 0.5 and y.max() < 0.5
    x, y = _where(png, (0xD6, 0x27, 0x28))  # tab:red: the caption, under the panels
    assert len(x) > 10 and y.min() > 0.95
    x, y = _where(png, (0x2C, 0xA0, 0x2C))  # tab:green: the markers, bottom right
    assert len(x) > 50 and x.min() > 0.5 and y.min() > 0.5


def test_values_colour_the_markers_and_an_image_fills_its_extent(tmp_path):
    rgba = np.zeros((2, 2, 4), dtype=np.uint8)
    rgba[..., 2] = rgba[..., 3] = 255  # blue, opaque
    p = panel([line([0.0, 1.0], [0.0, 1.0], marker="o", values=[0.0, 1.0], size=12.0)],
              xlabel="x [m]", ylabel="y [m]", colorbar="K_c [1]")  # fmt: skip
    p["images"] = [{"rgba": rgba, "x": 0.5, "y": 0.5, "dw": 0.5, "dh": 0.5}]
    p["xlim"], p["ylim"] = [0.0, 1.0], [0.0, 1.0]
    png = draw_png(sheet([p], (5.0, 4.0)), tmp_path / "map.png")
    x, y = _where(png, (0, 0, 255))
    assert len(x) > 1000 and x.min() > 0.3 and y.max() < 0.6  # the upper right quarter
    assert len(_where(png, (0xFD, 0xE7, 0x25))[0]) > 20  # viridis' yellow: value 1 and its key


def test_titles_keep_matplotlibs_sizes_unless_the_spec_sets_them():
    from matplotlib import rcParams
    from matplotlib.font_manager import FontProperties

    from glider_cosim.figures.mpl import draw

    p = panel([line([0, 1], [0, 1])], title="plain", xlabel="t [s]", ylabel="z [m]")
    small = {**p, "title": "small", "title_pt": 9.0, "col": 1}
    fig = draw({**sheet([p, small], (6.0, 3.0)), "suptitle": "over"})
    large = FontProperties(size=rcParams["axes.titlesize"]).get_size_in_points()
    assert [ax.title.get_fontsize() for ax in fig.get_axes()] == [large, 9.0]
    assert (
        fig.get_suptitle() == "over"
        and fig._suptitle.get_fontsize()
        == FontProperties(size=rcParams["figure.titlesize"]).get_size_in_points()
    )
