"""Interactive HTML pages of a run's or a report's figures (``plots.html``, ``report.html``).

The figures are the PNGs' own matplotlib figures, read back artist by artist
(:func:`figure_spec`: every line with its label, colour and style, the equilibrium and
event lines, images, the axes' titles, labels and limits), so what a figure shows is
defined once, where the PNG is drawn. :func:`write_page` draws them with bokeh into one
self-contained file: bokeh's JavaScript inline from the installed package, nothing fetched;
each figure zooms (box and wheel), shows values on hover and hides a series clicked in its
legend. No data are downsampled.
"""

from __future__ import annotations

import html
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

#: the ``class`` of each figure's ``<div>`` in a page (a test counts them after load)
FIGURE_CLASS = "glider-figure"
#: matplotlib line styles -> bokeh dash patterns
_DASH = {"-": "solid", "--": "dashed", "-.": "dashdot", ":": "dotted", "None": "solid"}


#: matplotlib markers -> bokeh's
_MARKERS = {"o": "circle", "D": "diamond", "X": "x", "x": "x", "^": "triangle",
            "v": "inverted_triangle", "s": "square"}  # fmt: skip


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
        "step": str(line.get_drawstyle()).startswith("steps"),
    }


def _image(im: Any) -> dict[str, Any]:
    arr = np.ma.masked_invalid(np.asarray(im.get_array(), dtype=float))
    rgba = (im.to_rgba(arr, bytes=True)).astype(np.uint8)
    x0, x1, y0, y1 = (float(v) for v in im.get_extent())
    if im.origin == "upper":
        rgba, arr = rgba[::-1], arr[::-1]
        y0, y1 = y1, y0
    return {"rgba": rgba, "value": arr.filled(np.nan), "x": min(x0, x1), "y": min(y0, y1),
            "dw": abs(x1 - x0), "dh": abs(y1 - y0)}  # fmt: skip


def figure_spec(fig: Any, title: str = "") -> dict[str, Any]:
    """What a matplotlib figure draws, as plain data: ``{"title", "notes", "panels"}``.

    Each panel is one axes: ``title``, ``xlabel``, ``ylabel``, ``xlim``, ``ylim``
    (data units), ``inverted`` (y), ``log`` (y), ``row``/``col`` (its place, from its
    position in the figure), ``lines`` (series, equilibrium and event lines; x and y in
    the axes' data units), ``images`` and ``texts``; ``notes`` are the figure's legend
    entries that are not lines (e.g. an image's colour key). Only visible axes count.
    """
    from matplotlib.lines import Line2D

    supt = [t.get_text() for t in _suptitles(fig)]
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
            "texts": [{"x": float(t.get_position()[0]), "y": float(t.get_position()[1]),
                       "text": t.get_text()} for t in ax.texts
                      if t.get_transform() == ax.transData and t.get_text()],
        })  # fmt: skip
    notes = []
    for leg in list(fig.legends) + [ax.get_legend() for ax in axes if ax.get_legend()]:
        for handle, text in zip(leg.legend_handles, leg.get_texts(), strict=False):
            if not isinstance(handle, Line2D) and text.get_text():
                notes.append(text.get_text())
    first = next((p["title"] for p in panels if p["title"]), "")
    return {"title": title or "\n".join(t for t in supt if t) or first, "notes": notes,
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


def _suptitles(fig: Any) -> list[Any]:
    out = [fig._suptitle] if getattr(fig, "_suptitle", None) is not None else []
    for sub in getattr(fig, "subfigs", ()):
        out += _suptitles(sub)
    return out


def _panel(spec: dict[str, Any], x_range: Any, label_width: int) -> Any:
    from bokeh.models import ColumnDataSource, HoverTool, Label, Range1d
    from bokeh.plotting import figure

    ylo, yhi = spec["ylim"]
    kw: dict[str, Any] = {"y_axis_type": "log"} if spec["log"] else {}
    p = figure(title=spec["title"] or None, x_axis_label=spec["xlabel"] or None,
               y_axis_label=spec["ylabel"] or None, height=320, sizing_mode="stretch_width",
               tools="xbox_zoom,box_zoom,wheel_zoom,pan,reset,save",
               active_drag="box_zoom", active_scroll="wheel_zoom",
               x_range=x_range or Range1d(*spec["xlim"]),
               y_range=Range1d(yhi, ylo) if spec["inverted"] else Range1d(ylo, yhi),
               **kw)  # fmt: skip
    xl, yl = spec["xlabel"] or "x", spec["ylabel"] or "y"
    for im in spec["images"]:
        h, w = im["rgba"].shape[:2]
        src = ColumnDataSource({"image": [im["rgba"].view(np.uint32).reshape(h, w)],
                                "value": [im["value"]]})  # fmt: skip
        r = p.image_rgba(image="image", x=im["x"], y=im["y"], dw=im["dw"], dh=im["dh"],
                         source=src)  # fmt: skip
        p.add_tools(HoverTool(renderers=[r], tooltips=[(xl, "$x{0.[000]}"),
                                                       (yl, "$y{0.[000]}"),
                                                       ("value", "@value")]))  # fmt: skip
    hovered = []
    for ln in spec["lines"]:
        src = ColumnDataSource({"x": ln["x"], "y": ln["y"]})
        common = {"source": src, "color": ln["color"], "alpha": ln["alpha"], "name": ln["name"]}
        if ln["legend"]:
            common["legend_label"] = ln["name"]
        if ln["lines"]:
            draw = p.step if ln["step"] else p.line
            extra = {"mode": "after"} if ln["step"] else {}
            hovered.append(draw("x", "y", line_width=ln["width"], line_dash=ln["dash"],
                                **extra, **common))  # fmt: skip
        if ln["marker"]:
            shape = _MARKERS.get(ln["marker"], "circle")
            hovered.append(p.scatter("x", "y", marker=shape, size=max(ln["size"] * 1.5, 2.5),
                                     **common))  # fmt: skip
    if hovered:
        p.add_tools(HoverTool(renderers=hovered, tooltips=[("", "$name"),
                                                           (xl, "@x{0.[000]}"),
                                                           (yl, "@y{0.[0000]}")]))  # fmt: skip
    for t in spec["texts"]:
        p.add_layout(Label(x=t["x"], y=t["y"], text=t["text"], text_font_size="8pt"))
    if not p.legend and label_width:  # as wide a margin as a legend: x axes aligned
        p.min_border_right = label_width + 70
    if p.legend:
        p.legend.click_policy = "hide"
        p.legend.label_text_font_size = "8pt"
        p.legend.background_fill_alpha = 0.7
        p.legend.label_width = label_width  # the same in every panel: x axes aligned
        p.add_layout(p.legend[0], "right")
    return p


def _figure_model(spec: dict[str, Any]) -> Any:
    """One figure: its panels on their grid, x ranges shared down each column."""
    from bokeh.layouts import gridplot
    from bokeh.models import Range1d

    nrow = 1 + max(p["row"] for p in spec["panels"])
    ncol = 1 + max(p["col"] for p in spec["panels"])
    grid: list[list[Any]] = [[None] * ncol for _ in range(nrow)]
    shared: dict[int, Any] = {}
    names = [ln["name"] for p in spec["panels"] for ln in p["lines"] if ln["legend"]]
    label_width = 6 * max((len(n) for n in names), default=0)
    for p in spec["panels"]:
        if p["images"]:
            rng = Range1d(*p["xlim"])
        else:
            rng = shared.setdefault(p["col"], Range1d(*p["xlim"]))
        if p["title"] == spec["title"]:  # the page's heading says it already
            p = {**p, "title": ""}
        grid[p["row"]][p["col"]] = _panel(p, rng, label_width)
    return gridplot(grid, sizing_mode="stretch_width", merge_tools=False, toolbar_location=None)


def _text(value: Any) -> str:
    """``{"plant": "python", ...}`` -> ``plant python, ...``; an empty one -> ``none``."""
    if isinstance(value, dict):
        return ", ".join(f"{k} {_text(v)}" for k, v in value.items()) or "none"
    return str(value)


def _settings_html(settings: dict[str, Any]) -> str:
    """A table; for many runs (a report), one collapsed block per run."""
    nested = all(isinstance(v, dict) for v in settings.values())
    if nested:
        blocks = [  # a block without a status (how a report was made) starts open
            f"<details{'' if 'status' in v else ' open'}><summary>{html.escape(str(k))}"
            f"{': ' + html.escape(_text(v['status'])) if 'status' in v else ''}"
            f"</summary>{_settings_html(v)}</details>"
            for k, v in settings.items()
        ]
        return "<h2>Runs and their settings</h2>" + "".join(blocks)
    rows = [f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(_text(v))}</td></tr>"
            for k, v in settings.items()]  # fmt: skip
    return "<table class='settings'>" + "".join(rows) + "</table>"


_CSS = """body{font-family:sans-serif;margin:1em 2em;color:#222}
h2{font-size:1.1em;margin:1.6em 0 .2em;white-space:pre-line}
p.notes{color:#555;font-size:.85em;margin:.2em 0}
table.settings{border-collapse:collapse;font-size:.85em}
table.settings th{text-align:left;padding:2px 12px 2px 0;vertical-align:top}
table.settings td{font-family:monospace;word-break:break-all}
details{font-size:.85em;margin:.1em 0}summary{cursor:pointer}
p.help{color:#555;font-size:.85em}"""


def write_page(
    path: str | Path,
    title: str,
    figures: Sequence[dict[str, Any]],
    settings: dict[str, Any],
) -> Path:
    """Write one self-contained HTML page of ``figures`` (from :func:`figure_spec`).

    Parameters
    ----------
    path : str or Path
        The ``.html`` file written (replaced whole: written beside it, then renamed).
    title : str
        The page's heading.
    figures : sequence of dict
        One spec per figure, drawn in this order.
    settings : dict
        What the page records about the run(s): shown as a table and kept as JSON in
        the ``<script type="application/json" id="run-settings">`` element.
    """
    from bokeh.embed import components
    from bokeh.resources import Resources

    if not figures:
        raise PageError(f"{path}: no figures to write; expected at least one")
    path = Path(path)
    models = [_figure_model(f) for f in figures]
    script, divs = components(models)
    body = []
    for spec, div in zip(figures, divs, strict=True):
        body.append(f"<h2>{html.escape(spec['title'])}</h2>")
        if spec["notes"]:
            body.append(f"<p class='notes'>{html.escape('; '.join(spec['notes']))}</p>")
        body.append(f"<div class='{FIGURE_CLASS}'>{div}</div>")
    data = json.dumps(settings, default=str).replace("</", "<\\/")
    js = Resources(mode="inline", components=["bokeh"]).render_js()  # bokeh.min.js alone
    text = (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><style>{_CSS}</style>"
        f"{js}{script}</head><body><h1>{html.escape(title)}</h1>"
        "<p class='help'>Drag to zoom (toolbar: x-only or box zoom), wheel to zoom, "
        "double-click or reset to restore; hover a curve for its values; click a legend "
        "entry to hide or show that series.</p>"
        f"{_settings_html(settings)}{''.join(body)}"
        f"<script type='application/json' id='run-settings'>{data}</script></body></html>\n"
    )
    tmp = path.with_name(path.name + ".part")
    try:
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(path)
    except OSError as err:
        tmp.unlink(missing_ok=True)
        raise PageError(f"{path}: cannot write the page ({err.strerror or err})") from None
    return path


def run_settings(metrics: dict[str, Any]) -> dict[str, Any]:
    """A run's settings as ``metrics.json`` records them: scenario, overrides, options,
    each FMU's flavor and FMI version, the package version."""
    run = metrics.get("run") or {}
    fmus = run.get("fmus") or {}
    return {
        "scenario": run.get("scenario", metrics.get("scenario", "?")),
        "scenario_source": run.get("scenario_source", ""),
        "overrides": run.get("overrides", {}),
        "options": run.get("options", {}),
        "flavor": {k: v.get("flavor") for k, v in fmus.items()},
        "fmi_version": {k: v.get("fmi_version") for k, v in fmus.items()},
        "fmu_version": {k: v.get("version") for k, v in fmus.items()},
        "package": f"{run.get('package', 'glider-cosim')} {run.get('package_version', '?')}",
        "status": metrics.get("status", ""),
    }


def write_run_page(result: Any, out: Path, figures: Sequence[Any]) -> dict[str, Path]:
    """``plots.html`` of a run from its PNG figures (closed here). A page that cannot be
    written is a logged warning: the run's results and PNGs stay as written."""
    import logging

    import matplotlib.pyplot as plt

    path = Path(out) / "plots.html"
    try:
        specs = [figure_spec(f, title=_first_title(f)) for f in figures]
        name = result.scenario.name
        return {"page": write_page(path, f"glider-cosim run: {name}", specs,
                                   run_settings(result.metrics))}  # fmt: skip
    except (PageError, OSError, ValueError, TypeError, ImportError) as err:
        logging.getLogger(__name__).warning("plots.html not written (%s); the run's "
                                            "results and PNGs are kept", err)  # fmt: skip
        return {}
    finally:
        for f in figures:
            plt.close(f)


def _first_title(fig: Any) -> str:
    return next((ax.get_title() for ax in fig.get_axes() if ax.get_title()), "")


class keep_figures:  # noqa: N801 - used as a context manager, like contextlib's
    """Within the block, ``matplotlib.pyplot.close(fig)`` keeps ``fig`` (in the list the
    block gets) instead of closing it: the report's plotting functions close their
    figures after saving the PNG, and the page draws them again. Closed on exit."""

    def __enter__(self) -> list[Any]:
        import matplotlib.pyplot as plt

        self._plt, self._close, self.figures = plt, plt.close, []
        plt.close = self._keep
        return self.figures

    def _keep(self, fig: Any = None) -> None:
        if fig is None or isinstance(fig, str | int):
            self._close(fig)
        elif fig not in self.figures:
            self.figures.append(fig)

    def __exit__(self, *exc: object) -> None:
        self._plt.close = self._close
        for f in self.figures:
            self._close(f)


def write_report_page(out: Path, figures: Sequence[Any], settings: dict[str, Any]) -> dict:
    """``report.html`` from the report's PNG figures; a failure is a logged warning
    (report.md, report.json and the PNGs stay as written)."""
    import logging

    path = Path(out) / "report.html"
    try:
        specs = [figure_spec(f) for f in figures]
        return {"page": write_page(path, "glider-cosim report", specs, settings)}
    except (PageError, OSError, ValueError, TypeError, ImportError) as err:
        logging.getLogger(__name__).warning("report.html not written (%s); report.md and "
                                            "its PNGs are kept", err)  # fmt: skip
        return {}
