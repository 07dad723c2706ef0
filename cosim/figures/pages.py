"""Interactive HTML pages of a run's or a report's figures (``plots.html``, ``report.html``),
built with bokeh's Python API.

A run's figures are its plots' specs (:mod:`.plots`), the ones its PNGs are drawn from;
a report's are its figures' specs, the ones its PNGs are drawn from (by :mod:`.mpl`).
Either way what a figure shows is defined once, in its spec. :func:`write_page` builds
each spec's panels with :mod:`bokeh.plotting` (a grid of them with
:func:`bokeh.layouts.gridplot`, x ranges shared down each column) and writes them into
one self-contained file: the models embedded with :func:`bokeh.embed.components`,
bokeh's JavaScript inline (:data:`bokeh.resources.INLINE`), nothing fetched. Each figure
zooms (box and wheel), shows values on hover and hides a series clicked in its legend.
A figure of one column has its legends on the right; a grid (more columns) has one
legend under it, whose entries hide or show that series in every panel, and each row
heading (a subfigure's title) over its rows, so that every panel keeps its column's
width. No data are downsampled; arrays go in as bokeh sends numpy arrays (base64 of
their bytes), so every value is exact.

bokeh is the ``pages`` extra (``pip install 'glider-cosim[pages]'``): without it a run
writes its PNGs and says in one line that ``plots.html`` needs it.
"""

from __future__ import annotations

import html
import json
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..extras import MissingExtra, require


class PageError(ValueError):
    """A figure that cannot be drawn as a page, or a page that cannot be written."""


#: the ``class`` of each figure's ``<div>`` in a page (a test counts them after load)
FIGURE_CLASS = "glider-figure"
#: the ``name`` of the bokeh plot that holds a grid's one legend
LEGEND_NAME = "glider-legend"
#: matplotlib markers -> bokeh's
MARKERS = {"o": "circle", "D": "diamond", "X": "x", "x": "x", "^": "triangle",
           "v": "inverted_triangle", "s": "square", "*": "star"}  # fmt: skip
#: the panels' tools (``xbox_zoom``: a drag zooms along x only)
TOOLS = "xbox_zoom,box_zoom,wheel_zoom,pan,reset,save"
#: a grid's legend: the widest row, px; an entry's swatch and gaps, px, and a label's
#: width per character (9 pt); the padding around its rows, px
LEGEND_ROW_PX = 900
LEGEND_ENTRY_PX = 45
LEGEND_CHAR_PX = 7
LEGEND_PADDING_PX = 6


def _legend_width(specs: Sequence[dict[str, Any]]) -> int:
    """The legend's label width, px: one for every panel of the page's one-column figures,
    so that their x axes line up (a grid's legend is under it)."""
    names = [ln["name"] for s in specs if all(p["col"] == 0 for p in s["panels"])
             for p in s["panels"] for ln in p["lines"] if ln["legend"]]  # fmt: skip
    return 6 * max((len(n) for n in names), default=0)


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
span.key{display:inline-block;width:1.6em;height:.9em;margin-right:.3em;vertical-align:middle}
table.settings{border-collapse:collapse;font-size:.85em}
table.settings th{text-align:left;padding:2px 12px 2px 0;vertical-align:top}
table.settings td{font-family:monospace;word-break:break-all}
details{font-size:.85em;margin:.1em 0}summary{cursor:pointer}
p.help{color:#555;font-size:.85em}
h3.glider-row{font-size:1em;margin:.9em 0 .1em;padding-bottom:.1em;border-bottom:1px solid #ccc}
div.glider-legend{margin:.4em 0 0}"""


def _wrap(text: str, width: int) -> str:
    """Each line of ``text`` at most ``width`` characters, broken at spaces (never inside
    ``K_c = 2``)."""
    lines = text.replace(" = ", "\u00a0=\u00a0").split("\n")
    return "\n".join("\n".join(textwrap.wrap(ln, width, break_long_words=False,
                                             break_on_hyphens=False) or [""])
                     for ln in lines)  # fmt: skip


def _panel(s: dict[str, Any], x_range: Any, label_width: int, grid: int) -> tuple[Any, list]:
    """One panel as a bokeh figure, and its legend entries for a grid's legend
    (``(line spec, renderers)``). ``grid``: the title's line length, characters (0: a
    figure of one column)."""
    from bokeh.models import ColumnDataSource, HoverTool, Label, Legend, NoOverlap, Range1d
    from bokeh.plotting import figure

    ylo, yhi = s["ylim"]
    kw: dict[str, Any] = {"y_axis_type": "log"} if s["log"] else {}
    if s["title"]:
        kw["title"] = _wrap(s["title"], grid) if grid else s["title"]
    p = figure(height=280 if grid else 320, sizing_mode="stretch_width", tools=TOOLS,
               active_drag="box_zoom", active_scroll="wheel_zoom", x_range=x_range,
               y_range=Range1d(yhi, ylo) if s["inverted"] else Range1d(ylo, yhi),
               x_axis_label=s["xlabel"] or None, y_axis_label=s["ylabel"] or None,
               **kw)  # fmt: skip
    if grid and s["title"]:
        p.title.text_font_size = "12px"
    for ax in (*p.xaxis, *p.yaxis):  # a label that would touch one is left out
        ax.major_label_policy = NoOverlap(min_distance=6)
        if grid and hasattr(ax.ticker, "desired_num_ticks"):
            ax.ticker.desired_num_ticks = 5
    xl, yl = s["xlabel"] or "x", s["ylabel"] or "y"
    for im in s["images"]:
        h, w = im["rgba"].shape[:2]
        rgba = np.ascontiguousarray(im["rgba"], dtype=np.uint8).view(np.uint32).reshape(h, w)
        value = np.asarray(im["value"])
        value = value.tolist() if value.dtype == object else value.astype(float)
        src = ColumnDataSource({"image": [rgba], "value": [value]})
        r = p.image_rgba(image="image", x=im["x"], y=im["y"], dw=im["dw"], dh=im["dh"],
                         source=src)  # fmt: skip
        p.add_tools(
            HoverTool(
                renderers=[r],
                tooltips=[(xl, "$x{0.[000]}"), (yl, "$y{0.[000]}"), ("value", "@value")],
            )
        )
    legend = not grid and any(ln["legend"] for ln in s["lines"])
    if legend:  # beside the panel; the lines' legend labels go into it
        legend_model = Legend(click_policy="hide", label_text_font_size="8pt",
                              background_fill_alpha=0.7, label_width=label_width)  # fmt: skip
        p.add_layout(legend_model, "right")
    elif label_width and not grid:
        p.min_border_right = label_width + 70  # as wide a margin as a legend: x axes aligned
    hovered, keys = [], []
    for ln in s["lines"]:
        src = ColumnDataSource({"x": ln["x"], "y": ln["y"]})
        common: dict[str, Any] = {"source": src, "alpha": ln["alpha"], "name": ln["name"]}
        if ln["legend"] and not grid:
            common["legend_label"] = ln["name"]
        mine = []
        if ln["lines"]:
            style = {"line_width": ln["width"], "line_dash": ln["dash"], "color": ln["color"]}
            if ln["step"]:
                mine.append(p.step("x", "y", mode="after", **style, **common))
            else:
                mine.append(p.line("x", "y", **style, **common))
        if ln["marker"]:
            mine.append(p.scatter("x", "y", marker=MARKERS.get(ln["marker"], "circle"),
                                  size=max(ln["size"] * 1.5, 2.5), fill_color=ln["color"],
                                  line_color=ln["edge"], **common))  # fmt: skip
        hovered += mine
        if ln["legend"] and grid:
            keys.append((ln, mine))
    if hovered:
        p.add_tools(HoverTool(renderers=hovered, tooltips=[("", "$name"), (xl, "@x{0.[000]}"),
                                                           (yl, "@y{0.[0000]}")]))  # fmt: skip
    for t in s["texts"]:
        p.add_layout(Label(x=t["x"], y=t["y"], text=t["text"], text_font_size="8pt"))
    return p, keys


def _grid_legend(keys: Sequence[tuple[dict[str, Any], list]]) -> Any:
    """One legend under a grid: an entry per name and style (its glyphs drawn from a
    stand-in renderer without data), whose click hides or shows that series in every
    panel (the stand-in's ``visible`` linked to each renderer's: ``js_link``)."""
    from bokeh.models import Legend, LegendItem
    from bokeh.plotting import figure

    found: dict[tuple, tuple[dict[str, Any], list]] = {}
    for ln, renderers in keys:
        key = (ln["name"], ln["color"], ln["dash"], ln["marker"])
        found.setdefault(key, (ln, []))[1].extend(renderers)
    widths = [LEGEND_ENTRY_PX + LEGEND_CHAR_PX * len(ln["name"]) for ln, _ in found.values()]
    ncols = max(1, min(len(widths), LEGEND_ROW_PX // max(widths)))
    rows = -(-len(widths) // ncols)
    p = figure(height=2 * LEGEND_PADDING_PX + 23 * rows, sizing_mode="stretch_width",
               toolbar_location=None, x_axis_location=None, y_axis_location=None,
               outline_line_color=None, min_border=0, name=LEGEND_NAME)  # fmt: skip
    p.grid.visible = False
    items = []
    for ln, renderers in found.values():
        # one point that is not drawn (a glyph without data draws no legend swatch)
        empty = {"x": [np.nan], "y": [np.nan], "alpha": max(ln["alpha"], 0.5)}
        stand_ins = []
        if ln["lines"]:
            stand_ins.append(p.line(line_width=max(ln["width"], 1.0), line_dash=ln["dash"],
                                    color=ln["color"], **empty))  # fmt: skip
        if ln["marker"]:
            marker = MARKERS.get(ln["marker"], "circle")
            stand_ins.append(p.scatter(marker=marker, size=7, fill_color=ln["color"],
                                       line_color=ln["edge"], **empty))  # fmt: skip
        for stand_in in stand_ins:
            for r in renderers:
                stand_in.js_link("visible", r, "visible")
        items.append(LegendItem(label=ln["name"], renderers=stand_ins))
    p.add_layout(Legend(items=items, orientation="horizontal", ncols=ncols, margin=0,
                        padding=LEGEND_PADDING_PX, spacing=14, location="top_left",
                        click_policy="hide", label_text_font_size="9pt", border_line_alpha=0,
                        background_fill_alpha=0), "center")  # fmt: skip
    return p


def _figure(spec: dict[str, Any], label_width: int) -> list[tuple[str, Any]]:
    """A figure's parts in page order: ``("heading", text)``, ``("grid", a gridplot of
    rows under one heading)``, and for a grid ``("legend", its legend)``. One x range
    is shared down each column (across the headings too: one document)."""
    from bokeh.layouts import gridplot
    from bokeh.models import Range1d

    panels = spec["panels"]
    nrow, ncol = 1 + max(p["row"] for p in panels), 1 + max(p["col"] for p in panels)
    grid = ncol > 1
    cells: list[list[Any]] = [[None] * ncol for _ in range(nrow)]
    shared: dict[int, Any] = {}
    heading, keys = [""] * nrow, []
    for s in panels:
        if s["images"]:
            xr = Range1d(*s["xlim"])
        else:
            xr = shared.setdefault(s["col"], Range1d(*s["xlim"]))
        shown = {**s, "title": ""} if s["title"] == spec["title"] else s
        p, mine = _panel(shown, xr, label_width, (36 if ncol > 2 else 60) if grid else 0)
        cells[s["row"]][s["col"]] = p
        keys += mine
        if s.get("heading"):
            heading[s["row"]] = s["heading"]
    parts: list[tuple[str, Any]] = []
    r0 = 0
    while r0 < nrow:
        r1 = r0 + 1
        while r1 < nrow and heading[r1] == heading[r0]:
            r1 += 1
        if heading[r0]:
            parts.append(("heading", heading[r0]))
        parts.append(("grid", gridplot(cells[r0:r1], sizing_mode="stretch_width",
                                       merge_tools=False, toolbar_location=None)))  # fmt: skip
        r0 = r1
    if keys:
        parts.append(("legend", _grid_legend(keys)))
    return parts


def write_page(
    path: str | Path,
    title: str,
    figures: Sequence[dict[str, Any]],
    settings: dict[str, Any],
) -> Path:
    """Write one self-contained HTML page of ``figures`` (specs: :mod:`.spec`), drawn by
    bokeh.

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

    Raises
    ------
    MissingExtra
        bokeh is not installed (the ``pages`` extra).
    PageError
        No figures, or the page cannot be written.
    """
    if not figures:
        raise PageError(f"{path}: no figures to write; expected at least one")
    require("pages")
    from bokeh.embed import components
    from bokeh.resources import Resources

    path = Path(path)
    label_width = _legend_width(figures)
    laid = [_figure(spec, label_width) for spec in figures]
    roots = [part for parts in laid for kind, part in parts if kind != "heading"]
    script, divs = components(roots)  # one document: ranges shared across a figure's rows
    divs = iter(divs)
    body = []
    for i, (spec, parts) in enumerate(zip(figures, laid, strict=True)):
        body.append(f"<h2>{html.escape(spec['title'])}</h2>")
        if spec["notes"]:
            keys = [(f"<span class='key' style='background:{n['color']}'></span>" if n["color"]
                     else "") + html.escape(n["text"]) for n in spec["notes"]]  # fmt: skip
            body.append(f"<p class='notes'>{' &nbsp; '.join(keys)}</p>")
        inner = []
        for kind, part in parts:
            if kind == "heading":
                inner.append(f"<h3 class='glider-row'>{html.escape(part)}</h3>")
            elif kind == "legend":
                inner.append(f"<div class='glider-legend'>{next(divs)}</div>")
            else:
                inner.append(f"<div>{next(divs)}</div>")
        body.append(f"<div class='{FIGURE_CLASS}'><div id='glider-figure-{i}'>"
                    f"{''.join(inner)}</div></div>")  # fmt: skip
    data = json.dumps(settings, default=str).replace("</", "<\\/")
    bokeh_js = Resources(mode="inline", components=["bokeh"]).render_js()
    text = (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><style>{_CSS}</style>"
        f"{bokeh_js}{script}</head><body><h1>{html.escape(title)}</h1>"
        "<p class='help'>Drag to zoom (toolbar: x-only or box zoom), wheel to zoom, "
        "double-click or reset to restore; hover a curve for its values; click a legend "
        "entry to hide or show that series (a legend under a grid: in each of its panels).</p>"
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


def write_run_page(result: Any, out: Path, specs: Sequence[dict[str, Any]]) -> dict[str, Path]:
    """``plots.html`` of a run from its plots' specs (:func:`~.plots.build_specs`), in this
    order. A page that cannot be written is a logged warning: the run's results and PNGs
    stay as written."""
    path = Path(out) / "plots.html"
    try:
        name = result.scenario.name
        return {"page": write_page(path, f"glider-cosim run: {name}", specs,
                                   run_settings(result.metrics))}  # fmt: skip
    except (PageError, MissingExtra, OSError, ValueError, TypeError) as err:
        page_not_written(err)
        return {}


def page_not_written(err: BaseException | str) -> None:
    """The warning of a ``plots.html`` that could not be written."""
    import logging

    logging.getLogger(__name__).warning("plots.html not written (%s); the run's results "
                                        "and PNGs are kept", err)  # fmt: skip


def write_report_page(out: Path, specs: Sequence[dict[str, Any]], settings: dict[str, Any]) -> dict:
    """``report.html`` from the report's figure specs (the ones its PNGs are drawn from:
    :mod:`.mpl`), in this order; a failure (bokeh missing too) is a logged warning
    (report.md, report.json and the PNGs stay as written)."""
    import logging

    path = Path(out) / "report.html"
    try:
        return {"page": write_page(path, "glider-cosim report", specs, settings)}
    except (PageError, MissingExtra, OSError, ValueError, TypeError) as err:
        logging.getLogger(__name__).warning("report.html not written (%s); report.md and "
                                            "its PNGs are kept", err)  # fmt: skip
        return {}
