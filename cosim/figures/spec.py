"""The plain-data spec of a figure: :mod:`.plots` makes a run's, :mod:`.mpl` draws
every spec as a PNG (matplotlib) and :mod:`.pages` a run's as ``plots.html``;
:func:`line`, :func:`panel` and :func:`figure` build one; :func:`exit_marks` marks where
a curve leaves its panel's limits. A sweep's and a report's figures are specs too
(:func:`sheet`).

A spec is ``{"title", "suptitle", "notes", "panels", "size_in", "height_ratios", ...}``
(the keys :mod:`.mpl` draws), each panel ``{"title", "xlabel", "ylabel", "xlim", "ylim",
"inverted", "log", "row", "col", "lines", "images", "texts", "legend_pt"}`` and each
line ``{"x", "y", "name", "legend", "color", "alpha", "width", "dash", "lines",
"marker", "size", "edge", "step", "span", "gid"}`` (x and y in data units; widths and
sizes in points).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

#: the colours the plots use (matplotlib's "tab" palette, by the names they had there)
COLORS = {
    "tab:blue": "#1f77b4",
    "tab:orange": "#ff7f0e",
    "tab:green": "#2ca02c",
    "tab:red": "#d62728",
    "tab:purple": "#9467bd",
    "tab:gray": "#7f7f7f",
    "darkred": "#8b0000",
    "k": "#000000",
}
#: figure sizes, inches: one panel, and two panels sharing their time axis
SIZES = {"single": (7.0, 3.6), "pair": (7.0, 5.2)}
#: margins (figure fractions) of the one-panel and the two-panel figures: fixed, as a
#: layout engine (tight, constrained) measuring every text first took half of a plot's
#: drawing time
SINGLE_MARGINS = {"left": 0.125, "right": 0.98, "bottom": 0.13, "top": 0.86}
PAIR_MARGINS = {"left": 0.125, "right": 0.98, "bottom": 0.09, "top": 0.9, "hspace": 0.1}
#: the run's PNGs: dots per inch (770 px wide), the grid lines' alpha, the subtitle's
#: size (points) and colour; zlib level 1 (a third of the default's time, files about a
#: fifth larger)
RUN_DPI, RUN_GRID, SUBTITLE_PT, SUBTITLE_COLOR = 110, 0.3, 7.5, "#4d4d4d"
#: autoscaled limits leave this fraction of the data's range on each side
AXIS_MARGIN = 0.05


def line(
    x: Any,
    y: Any,
    name: str = "",
    *,
    color: str = "tab:blue",
    width: float = 1.0,
    dash: str = "solid",
    alpha: float = 1.0,
    marker: str = "",
    size: float = 6.0,
    step: bool = False,
    span: str = "",
    gid: str = "",
    legend: bool | None = None,
    values: Any = None,
    edge: str = "",
) -> dict[str, Any]:
    """One line of a panel (a spec): ``x``, ``y`` in data units, ``width`` and ``size``
    (markers) in points, ``dash`` one of solid, dashed, dashdot, dotted; ``span``
    ``"x"`` for a vertical line across the panel at ``x[0]`` (``"y"``: horizontal, at
    ``y[0]``), its other coordinates set to the panel's limits by :func:`panel`;
    ``values`` (one per point, markers only) colour the markers by ``viridis`` instead
    of ``color`` (drawn by :mod:`.mpl`, with the panel's ``colorbar`` as their key);
    ``edge`` the markers' edge colour (``color`` if empty)."""
    rgb = COLORS.get(color, color)
    mapped = {} if values is None else {"values": np.asarray(values, dtype=float),
                                        "cmap": "viridis"}  # fmt: skip
    return {
        "x": np.asarray(x, dtype=float),
        "y": np.asarray(y, dtype=float),
        "name": name or gid.split(":", 1)[-1],
        "legend": bool(name) if legend is None else legend,
        "color": rgb,
        "alpha": float(alpha),
        "width": float(width),
        "dash": dash,
        "lines": not marker,
        "marker": marker,
        "size": float(size),
        "edge": COLORS.get(edge, edge) if edge else rgb,
        "step": step,
        "span": span,
        "gid": gid,
        **mapped,
    }


def _limits(values: list[np.ndarray]) -> list[float]:
    v = np.concatenate([np.asarray(a, dtype=float).ravel() for a in values] or [np.zeros(1)])
    v = v[np.isfinite(v)]
    lo, hi = (float(v.min()), float(v.max())) if len(v) else (0.0, 1.0)
    if hi - lo <= 1e-12 * max(1.0, abs(hi)):  # a constant: a range around it
        half = 0.05 * abs(hi) if hi else 0.05
        return [lo - half, hi + half]
    pad = AXIS_MARGIN * (hi - lo)
    return [lo - pad, hi + pad]


def panel(
    lines: Sequence[dict[str, Any]],
    *,
    title: str = "",
    xlabel: str = "",
    ylabel: str = "",
    row: int = 0,
    inverted: bool = False,
    grid: float = 0.0,
    colorbar: str = "",
    legend_pt: float = 7.0,
) -> dict[str, Any]:
    """A panel of ``lines`` (drawn in this order), its limits autoscaled from them (the
    span lines count where they stand), then the span lines run across it. ``grid``
    (the grid lines' alpha; none if 0) and ``colorbar`` (the label of the key of
    ``values``) are drawn by :mod:`.mpl`; a run's figures (:func:`figure`) have a grid."""
    xs = [ln["x"] for ln in lines if ln["span"] != "y"]
    ys = [ln["y"] for ln in lines if ln["span"] != "x"]
    xlim, ylim = _limits(xs), _limits(ys)
    _span(lines, xlim, ylim)
    return {"title": title, "xlabel": xlabel, "ylabel": ylabel, "xlim": xlim, "ylim": ylim,
            "inverted": inverted, "log": False, "row": row, "col": 0, "lines": list(lines),
            "images": [], "texts": [], "legend_pt": legend_pt,
            **({"grid": grid} if grid else {}),
            **({"colorbar": colorbar} if colorbar else {})}  # fmt: skip


def _span(lines: Sequence[dict[str, Any]], xlim: Sequence[float], ylim: Sequence[float]) -> None:
    for ln in lines:
        if ln["span"] == "x":
            ln["x"], ln["y"] = np.repeat(ln["x"][:1], 2), np.array(ylim)
        elif ln["span"] == "y":
            ln["x"], ln["y"] = np.array(xlim), np.repeat(ln["y"][:1], 2)


def set_limits(p: dict[str, Any], xlim: Any = None, ylim: Any = None) -> None:
    """Set a panel's limits (each left as it is if None); its span lines run across the
    new ones."""
    p["xlim"] = p["xlim"] if xlim is None else [float(v) for v in xlim]
    p["ylim"] = p["ylim"] if ylim is None else [float(v) for v in ylim]
    _span(p["lines"], p["xlim"], p["ylim"])


def share_x(panels: Sequence[dict[str, Any]]) -> None:
    """One x range for ``panels``, autoscaled from all their lines (the span lines where
    they stand), as matplotlib's ``sharex``."""
    xlim = _limits([ln["x"] for p in panels for ln in p["lines"] if ln["span"] != "y"])
    for p in panels:
        set_limits(p, xlim=xlim)


def exits(y: np.ndarray, lo: float, hi: float) -> list[tuple[int, bool]]:
    """Where the curve ``y`` leaves ``[lo, hi]`` (a panel's limits): (sample, above) of
    each exit, at each sample outside whose predecessor is inside or on the other side."""
    side = np.where(y > hi, 1, np.where(y < lo, -1, 0))
    prev = np.r_[0, side[:-1]]
    return [(int(k), bool(side[k] > 0)) for k in np.nonzero((side != 0) & (side != prev))[0]]


def exit_marks(t: np.ndarray, y: np.ndarray, lo: float, hi: float, colour: str,
                size: float) -> list[dict[str, Any]]:  # fmt: skip
    """A triangle at the axes' edge wherever ``y`` leaves ``[lo, hi]`` (:func:`exits`): the
    lines that mark a curve clipped at its panel's limits (the report's figures, Fig. 8)."""
    return [{**line([t[k]], [hi if above else lo], marker="^" if above else "v", color=colour,
                    size=size, width=1.5, gid="clipped"), "zorder": 5, "clip": False}
            for k, above in exits(y, lo, hi)]  # fmt: skip


def figure(kind: str, panels: Sequence[dict[str, Any]], subtitle: str = "") -> dict[str, Any]:
    """A run's figure spec of ``kind`` (``"single"``, or ``"pair"``: two panels, one time
    axis) with ``subtitle`` above its panels (a run's: its settings); each panel with a
    grid (:data:`RUN_GRID`), unless it has one."""
    for p in panels:
        p.setdefault("grid", RUN_GRID)
    return {
        "title": next((p["title"] for p in panels if p["title"]), ""),
        "suptitle": subtitle,
        "suptitle_pt": SUBTITLE_PT,
        "suptitle_color": SUBTITLE_COLOR,
        "notes": [],
        "panels": list(panels),
        "size_in": SIZES[kind],
        "dpi": RUN_DPI,
        "margins": PAIR_MARGINS if kind == "pair" else SINGLE_MARGINS,
        "compress_level": 1,
        "sharex": kind == "pair",
        "height_ratios": [2.0, 1.0] if kind == "pair" else [1.0],
    }


def sheet(
    panels: Sequence[dict[str, Any]], size_in: tuple[float, float], caption: str = ""
) -> dict[str, Any]:
    """A figure spec drawn by :mod:`.mpl` (a sweep's, a report's): ``panels`` in the grid
    of their ``row`` and ``col``, ``size_in`` inches, ``caption`` under them."""
    return {
        "title": next((p["title"] for p in panels if p["title"]), ""),
        "suptitle": "",
        "notes": [],
        "caption": caption,
        "panels": list(panels),
        "size_in": tuple(size_in),
    }
