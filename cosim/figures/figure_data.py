"""What a matplotlib figure draws, as plain data (:func:`figure_spec`): the input of the
results pages (:mod:`glider_cosim.figures.pages`), read back artist by artist so that a
figure's content is defined once, where its PNG is drawn."""

from __future__ import annotations

from typing import Any

import numpy as np

#: matplotlib line styles -> bokeh dash patterns
_DASH = {"-": "solid", "--": "dashed", "-.": "dashdot", ":": "dotted", "None": "solid"}


class PageError(ValueError):
    """A figure that cannot be drawn as a page, or a page that cannot be written."""


def _hex(color: Any, alpha: float | None = None) -> tuple[str, float]:
    from matplotlib.colors import to_hex, to_rgba

    rgba = to_rgba(color)
    return to_hex(rgba[:3]), float(rgba[3] if alpha is None else alpha)


def _label(artist: Any) -> str:
    label = str(artist.get_label() or "")
    return "" if label.startswith("_") else label


def _line(ax: Any, line: Any) -> dict[str, Any] | None:
    """One Line2D: a series in data coordinates, or an axvline/axhline across the axes."""
    x = np.asarray(line.get_xdata(), dtype=float)
    y = np.asarray(line.get_ydata(), dtype=float)
    if not len(x) or not line.get_visible():
        return None
    tr = line.get_transform()
    if tr == ax.get_xaxis_transform():  # axvline: x in data, y in axes fraction
        x, y = np.array([x[0], x[0]]), np.array(ax.get_ylim(), dtype=float)
    elif tr == ax.get_yaxis_transform():  # axhline
        x, y = np.array(ax.get_xlim(), dtype=float), np.array([y[0], y[0]])
    color, alpha = _hex(line.get_color(), line.get_alpha())
    gid = line.get_gid() or ""
    ls, marker = str(line.get_linestyle()), str(line.get_marker())
    return {
        "x": x,
        "y": y,
        "name": _label(line) or (gid.split(":", 1)[-1] if gid else ""),
        "legend": bool(_label(line)),
        "color": color,
        "alpha": alpha,
        "width": float(line.get_linewidth()),
        "dash": _DASH.get(ls, "solid"),
        "lines": ls not in ("None", "none", ""),
        "marker": marker if marker not in ("None", "none", "", " ") else "",
        "size": float(line.get_markersize()),
        "edge": _hex(line.get_markeredgecolor())[0],
        "step": str(line.get_drawstyle()).startswith("steps"),
    }


def _image(im: Any) -> dict[str, Any]:
    arr = np.ma.masked_invalid(np.asarray(im.get_array(), dtype=float))
    rgba = (im.to_rgba(arr, bytes=True)).astype(np.uint8)
    x0, x1, y0, y1 = (float(v) for v in im.get_extent())
    if im.origin == "upper":
        rgba, arr = rgba[::-1], arr[::-1]
        y0, y1 = y1, y0
    value: Any = arr.filled(np.nan)
    names = getattr(im, "value_names", None)  # a categorical image: hover shows the name
    if names is not None:
        value = np.array([[names[int(v)] if np.isfinite(v) and 0 <= v < len(names) else ""
                           for v in row] for row in value], dtype=object)  # fmt: skip
    return {"rgba": rgba, "value": value, "x": min(x0, x1), "y": min(y0, y1),
            "dw": abs(x1 - x0), "dh": abs(y1 - y0)}  # fmt: skip


def figure_spec(fig: Any, title: str = "") -> dict[str, Any]:
    """What a matplotlib figure draws, as plain data: ``{"title", "notes", "panels"}``.

    Each panel is one axes: ``title``, ``xlabel``, ``ylabel``, ``xlim``, ``ylim``
    (data units), ``inverted`` (y), ``log`` (y), ``row``/``col`` (its place, from its
    position in the figure), ``lines`` (series, equilibrium and event lines; x and y in
    the axes' data units), ``images``, ``texts`` and ``heading`` (the title of the
    subfigure it is in: a row heading, drawn over its rows); ``notes`` are the figure's
    legend entries that are not lines (e.g. an image's colour key). Only visible axes count.
    """
    from matplotlib.lines import Line2D

    supt = fig.get_suptitle()
    axes = [ax for ax in fig.get_axes() if ax.get_visible() and ax.has_data()]
    if not axes:
        raise PageError(f"figure {title or supt!r}: no axes with data; expected plotted axes")
    places = [_place(ax) for ax in axes]
    rows = sorted({r for r, _ in places})
    cols = sorted({c for _, c in places})
    panels = []
    for ax, (row, col) in zip(axes, places, strict=True):
        lines = [s for s in (_line(ax, ln) for ln in ax.get_lines()) if s is not None]
        panels.append({
            "title": ax.get_title() or ax.get_title("left"),
            "xlabel": ax.get_xlabel(), "ylabel": ax.get_ylabel(),
            "xlim": [float(v) for v in sorted(ax.get_xlim())],
            "ylim": [float(v) for v in sorted(ax.get_ylim())],
            "inverted": bool(ax.yaxis_inverted()), "log": ax.get_yscale() == "log",
            "row": rows.index(row), "col": cols.index(col),
            "lines": lines, "images": [_image(im) for im in ax.get_images()],
            "heading": _heading(ax),
            "texts": [{"x": float(t.get_position()[0]), "y": float(t.get_position()[1]),
                       "text": t.get_text()} for t in ax.texts
                      if t.get_transform() == ax.transData and t.get_text()],
        })  # fmt: skip
    notes = []
    for leg in list(fig.legends) + [ax.get_legend() for ax in axes if ax.get_legend()]:
        for handle, text in zip(leg.legend_handles, leg.get_texts(), strict=False):
            if not isinstance(handle, Line2D) and text.get_text():
                face = getattr(handle, "get_facecolor", None)
                notes.append({"text": text.get_text(), "color": _hex(face())[0] if face else ""})
    first = next((p["title"] for p in panels if p["title"]), "")
    return {"title": title or supt or first, "notes": notes,
            "panels": panels}  # fmt: skip


def _place(ax: Any) -> tuple[tuple[int, int], int]:
    """(row key, column) of an axes: its grid cell, rows of subfigures stacked in order."""
    ss = ax.get_subplotspec()
    if ss is None:
        p = ax.get_position()
        return (0, -round(p.y1 * 100)), round(p.x0 * 100)
    parent, root = ax.get_figure(root=False), ax.get_figure(root=True)
    subs = list(getattr(root, "subfigs", ()))
    return (subs.index(parent) if parent in subs else 0, ss.rowspan.start), ss.colspan.start


def _heading(ax: Any) -> str:
    """The title of the subfigure ``ax`` is in (its rows' heading); empty in a figure."""
    parent = ax.get_figure(root=False)
    if parent is ax.get_figure(root=True):
        return ""
    return parent.get_suptitle()
