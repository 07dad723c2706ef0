"""The results pages' figures drawn in the browser: the figure specs as data and the
script that builds each with BokehJS's own plotting API (``bokeh-api.min.js``), so that
writing a page imports no bokeh in Python (about 1 s of CPU a run; issue 31).

:func:`page_scripts` returns the ``<script>`` elements: bokeh's JavaScript inline from the
installed package (read as files, nothing fetched), the specs (arrays as base64 float64,
each distinct array once, so every value is exact) and :data:`RENDER`, which draws every
figure into its ``<div id="glider-figure-N">``: the panels on their grid, x ranges shared
down each column, box and wheel zoom, hover values, legends that hide a series on click,
tick labels that never touch. A figure of one column has its legends on the right; a
grid (more columns) has one legend under it, each row heading (a subfigure's title)
over its rows and no legend beside a panel, so that every panel keeps its column's width.
"""

from __future__ import annotations

import base64
import importlib.util
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np


class PageError(ValueError):
    """A figure that cannot be drawn as a page, or a page that cannot be written."""


#: what BokehJS needs: the library and its plotting API, in this order
BOKEH_FILES = ("bokeh.min.js", "bokeh-api.min.js")
#: matplotlib markers -> bokeh's
MARKERS = {"o": "circle", "D": "diamond", "X": "x", "x": "x", "^": "triangle",
           "v": "inverted_triangle", "s": "square", "*": "star"}  # fmt: skip
#: bokeh's named dash patterns as the on/off lengths, px, its Python API sends
DASHES = {"solid": [], "dashed": [6], "dotted": [2, 4], "dotdash": [2, 4, 6, 4],
          "dashdot": [6, 4, 2, 4]}  # fmt: skip

#: the figures' builder (the same models, options and styles as bokeh's Python API made)
RENDER = r"""
(function () {
const P = Bokeh.Plotting, D = window.GLIDER_PAGE, bin = (i) => D.arrays[i];
const nd = Bokeh.require("core/util/ndarray");
function decode(s, Kind) {
  const b = atob(s), u = new Uint8Array(b.length);
  for (let i = 0; i < b.length; i++) u[i] = b.charCodeAt(i);
  return new Kind(u.buffer);
}
D.arrays = D.arrays.map((s) => decode(s, Float64Array));
const range = (lo, hi) => new Bokeh.Range1d({start: lo, end: hi});
// a panel of a grid (a figure of more than one column) is narrower: fewer ticks; its
// legend is under the grid (:func:`legend`: one for every panel)
function wrap(text, width) {  // each line at most width characters, broken at spaces
  return text.split("\n").map((line) => {  // not inside "K_c = 2": no-break spaces there
    const out = [];
    for (const word of line.replace(/ = /g, "\u00a0=\u00a0").split(" ")) {
      const last = out.length - 1;
      if (last >= 0 && out[last].length + 1 + word.length <= width) out[last] += " " + word;
      else out.push(word);
    }
    return out.join("\n");
  }).join("\n");
}
// grid: the title's line length, characters (0: a figure of one column)
function panel(s, xr, lw, grid) {
  const [ylo, yhi] = s.ylim, kw = {
    height: grid ? 280 : 320, sizing_mode: "stretch_width", active_drag: "box_zoom",
    active_scroll: "wheel_zoom", tools: "xbox_zoom,box_zoom,wheel_zoom,pan,reset,save",
    x_range: xr, y_range: s.inverted ? range(yhi, ylo) : range(ylo, yhi)};
  if (s.title) kw.title = grid ? wrap(s.title, grid) : s.title;
  if (s.xlabel) kw.x_axis_label = s.xlabel;
  if (s.ylabel) kw.y_axis_label = s.ylabel;
  if (s.log) kw.y_axis_type = "log";
  const p = P.figure(kw), xl = s.xlabel || "x", yl = s.ylabel || "y", keys = [];
  if (grid && s.title) p.title.text_font_size = "12px";
  for (const ax of [...p.xaxes, ...p.yaxes]) {  // a label that would touch one is left out
    ax.major_label_policy = new Bokeh.NoOverlap({min_distance: 6});
    if (grid && ax.ticker.desired_num_ticks !== undefined) ax.ticker.desired_num_ticks = 5;
  }
  for (const im of s.images) {
    const shape = [im.h, im.w], image = nd.ndarray(decode(im.rgba, Uint32Array).buffer,
                                                    {dtype: "uint32", shape});
    const value = im.names ? nd.ndarray(im.value, {shape}) : nd.ndarray(
      decode(im.value, Float64Array).buffer, {dtype: "float64", shape});
    const src = new Bokeh.ColumnDataSource({data: {image: [image], value: [value]}});
    const r = p.image_rgba({image: {field: "image"}, x: im.x, y: im.y, dw: im.dw, dh: im.dh,
                            source: src});
    p.add_tools(new Bokeh.HoverTool({renderers: [r], tooltips: [[xl, "$x{0.[000]}"],
                                     [yl, "$y{0.[000]}"], ["value", "@value"]]}));
  }
  const hovered = [];
  for (const ln of s.lines) {
    const src = new Bokeh.ColumnDataSource({data: {x: bin(ln.x), y: bin(ln.y)}});
    const common = {source: src, alpha: ln.alpha, name: ln.name};
    if (ln.legend && !grid) common.legend_label = ln.name;
    const at = {x: {field: "x"}, y: {field: "y"}}, mine = [];
    if (ln.lines) {
      const extra = ln.step ? {mode: "after"} : {};
      mine.push((ln.step ? p.step : p.line).call(p, {...at, line_width: ln.width,
        line_dash: ln.dash, color: ln.color, ...extra, ...common}));
    }
    if (ln.marker) {
      mine.push(p.scatter({...at, marker: ln.marker, size: Math.max(ln.size * 1.5, 2.5),
        fill_color: ln.color, line_color: ln.edge, ...common}));
    }
    hovered.push(...mine);
    if (ln.legend && grid) keys.push({line: ln, renderers: mine});
  }
  if (hovered.length) {
    p.add_tools(new Bokeh.HoverTool({renderers: hovered, tooltips: [["", "$name"],
      [xl, "@x{0.[000]}"], [yl, "@y{0.[0000]}"]]}));
  }
  for (const t of s.texts) {
    p.add_layout(new Bokeh.Label({x: t.x, y: t.y, text: t.text, text_font_size: "8pt"}));
  }
  if (!grid && s.lines.some((ln) => ln.legend)) {
    const lg = p.legend;
    lg.click_policy = "hide";
    lg.label_text_font_size = "8pt";
    lg.background_fill_alpha = 0.7;
    lg.label_width = lw;  // the same in every panel: x axes aligned
    p.center = p.center.filter((r) => r !== lg);
    p.add_layout(lg, "right");
  } else if (lw && !grid) {
    p.min_border_right = lw + 70;  // as wide a margin as a legend: x axes aligned
  }
  return [p, keys];
}
// one legend under a grid: an entry per name and style, which hides or shows that
// series in every panel when clicked
function swatch(ln) {
  const svg = "http://www.w3.org/2000/svg", el = document.createElementNS(svg, "svg");
  el.setAttribute("width", "26");
  el.setAttribute("height", "12");
  const add = (tag, attrs) => {
    const e = document.createElementNS(svg, tag);
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
    e.setAttribute("opacity", Math.max(ln.alpha, 0.5));
    el.appendChild(e);
  };
  if (ln.lines) {
    add("line", {x1: 1, y1: 6, x2: 25, y2: 6, stroke: ln.color,
                 "stroke-width": Math.max(ln.width, 1), "stroke-dasharray": ln.dash.join(" ")});
  }
  if (ln.marker === "x") {
    add("path", {d: "M9 2L17 10M17 2L9 10", stroke: ln.color, "stroke-width": 2});
  } else if (ln.marker.includes("triangle")) {
    add("path", {d: ln.marker === "triangle" ? "M13 2L18 10L8 10Z" : "M13 10L18 2L8 2Z",
                 fill: ln.color});
  } else if (ln.marker) {
    add("circle", {cx: 13, cy: 6, r: 3.5, fill: ln.color, stroke: ln.edge});
  }
  return el;
}
function legend(keys) {
  const box = document.createElement("div"), found = new Map();
  box.className = "glider-legend";
  for (const k of keys) {
    const id = JSON.stringify([k.line.name, k.line.color, k.line.dash, k.line.marker]);
    if (!found.has(id)) found.set(id, {line: k.line, renderers: []});
    found.get(id).renderers.push(...k.renderers);
  }
  for (const e of found.values()) {
    const b = document.createElement("button");
    b.type = "button";
    b.className = "glider-key";
    b.title = "click: hide or show in every panel";
    b.append(swatch(e.line), e.line.name);
    b.addEventListener("click", () => {
      const on = !b.classList.toggle("off");
      for (const r of e.renderers) r.visible = on;
    });
    box.appendChild(b);
  }
  return box;
}
D.figures.forEach((f, i) => {
  const nrow = 1 + Math.max(...f.panels.map((p) => p.row));
  const ncol = 1 + Math.max(...f.panels.map((p) => p.col)), grid = ncol > 1;
  const cells = Array.from({length: nrow}, () => Array(ncol).fill(null)), shared = {};
  const heading = Array(nrow).fill(""), keys = [];
  for (const s of f.panels) {
    let xr;
    if (s.images.length) xr = range(...s.xlim);
    else xr = shared[s.col] || (shared[s.col] = range(...s.xlim));
    const [p, mine] = panel(s.title === f.title ? {...s, title: ""} : s, xr, D.label_width,
                            grid ? (ncol > 2 ? 36 : 60) : 0);
    cells[s.row][s.col] = p;
    keys.push(...mine);
    if (s.heading) heading[s.row] = s.heading;
  }
  // rows under one heading drawn together, the heading over them; one document, so
  // that the x ranges stay shared down each column across the headings
  const host = document.getElementById("glider-figure-" + i), doc = new Bokeh.Document();
  const places = [];
  for (let r0 = 0; r0 < nrow;) {
    let r1 = r0 + 1;
    while (r1 < nrow && heading[r1] === heading[r0]) r1++;
    if (heading[r0]) {
      const h = document.createElement("h3");
      h.className = "glider-row";
      h.textContent = heading[r0];
      host.appendChild(h);
    }
    places.push(host.appendChild(document.createElement("div")));
    doc.add_root(P.gridplot(cells.slice(r0, r1), {sizing_mode: "stretch_width",
                                                  merge_tools: false, toolbar_location: null}));
    r0 = r1;
  }
  Bokeh.embed.add_document_standalone(doc, host, places);
  if (keys.length) host.appendChild(legend(keys));
});
})();
"""


def _bokeh_js() -> str:
    """bokeh's JavaScript (:data:`BOKEH_FILES`) from the installed package, as
    ``<script>`` elements; found without importing bokeh."""
    spec = importlib.util.find_spec("bokeh")
    if spec is None or not spec.submodule_search_locations:
        raise PageError("bokeh is not installed; expected it for the pages (pip install bokeh)")
    folder = Path(next(iter(spec.submodule_search_locations))) / "server" / "static" / "js"
    parts = []
    for name in BOKEH_FILES:
        try:
            parts.append((folder / name).read_text(encoding="utf-8"))
        except OSError as err:
            raise PageError(f"{folder / name}: cannot be read ({err.strerror or err}); "
                            "expected bokeh's JavaScript there") from None  # fmt: skip
    return "".join(f'<script type="text/javascript">\n{js}\n</script>\n' for js in parts)


def _b64(values: Any) -> str:
    """An array as base64 of its little-endian float64 bytes (read back exactly)."""
    return base64.b64encode(np.ascontiguousarray(values, dtype="<f8").tobytes()).decode("ascii")


def _data(figures: Sequence[dict[str, Any]], label_width: int) -> dict[str, Any]:
    """The figure specs as JSON-able data: each line's x and y an index into ``arrays``."""
    arrays: list[str] = []
    seen: dict[str, int] = {}

    def ref(values: Any) -> int:
        text = _b64(values)
        if text not in seen:
            seen[text] = len(arrays)
            arrays.append(text)
        return seen[text]

    out = []
    for f in figures:
        panels = []
        for p in f["panels"]:
            lines = [{**ln, "x": ref(ln["x"]), "y": ref(ln["y"]),
                      "dash": DASHES.get(ln["dash"], []),
                      "marker": MARKERS.get(ln["marker"], "circle") if ln["marker"] else ""}
                     for ln in p["lines"]]  # fmt: skip
            images = []
            for im in p["images"]:
                h, w = im["rgba"].shape[:2]
                rgba = np.ascontiguousarray(im["rgba"], dtype=np.uint8).tobytes()
                value, names = np.asarray(im["value"]), np.asarray(im["value"]).dtype == object
                images.append({"rgba": base64.b64encode(rgba).decode("ascii"), "h": h, "w": w,
                               "names": bool(names), "x": im["x"], "y": im["y"],
                               "value": value.ravel().tolist() if names else _b64(value),
                               "dw": im["dw"], "dh": im["dh"]})  # fmt: skip
            panels.append({**p, "lines": lines, "images": images})
        out.append({"title": f["title"], "panels": panels})
    return {"arrays": arrays, "figures": out, "label_width": label_width}


def page_scripts(figures: Sequence[dict[str, Any]], label_width: int) -> str:
    """The ``<script>`` elements that draw ``figures`` (specs of
    :mod:`~glider_cosim.figures.spec`) into the page's
    ``<div id="glider-figure-N">`` elements, after the page has loaded."""
    data = json.dumps(_data(figures, label_width), allow_nan=True, default=float)
    data = data.replace("</", "<\\/")  # NaN and Infinity are JavaScript, not JSON
    return (f"{_bokeh_js()}<script type='text/javascript'>\nwindow.GLIDER_PAGE = {data};\n"
            "window.addEventListener('DOMContentLoaded', function () {\n"
            f"{RENDER}\n}});\n</script>")  # fmt: skip
