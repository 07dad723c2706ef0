"""A figure spec (:mod:`.spec`) drawn as a PNG with matplotlib: every PNG glider-cosim
writes (the run's plots, the sweep's, the report's) is drawn here.

What it draws of a spec: each panel at its ``row``/``col`` in a grid, its ``title``
(``title_pt``), ``ylabel_pt``, ``yticks`` (fixed), ``heading`` (panels of one heading:
a subfigure of its rows under it, in bold, ``heading_pt``),
``xlabel``, ``ylabel``, ``xlim``, ``ylim``, ``inverted``, ``log``, ``grid`` (the grid
lines' alpha, none if absent), ``legend_pt`` (its legend's size, where the legend covers
the fewest points: matplotlib's ``"best"``), ``colorbar`` (the label of the colour key
of the lines with ``values``), ``lines`` (a line with ``lines`` false is a scatter of
markers of ``size`` points, a matplotlib scatter if ``scatter`` or ``values``; ``values``
colour its markers by ``cmap``; ``step``: held values), ``images`` and ``texts``; the
figure's ``size_in``, ``dpi``, ``suptitle`` (``suptitle_pt``, ``suptitle_color``),
``notes`` (colour keys, one row under the panels),
``legend_below`` (one legend of the panels' lines under them, ``legend_ncol`` columns,
``legend_pt``, ``legend_order`` ``"column"``: its names down each column first;
``legend_columns``: false, of the first column's lines; true, one under
each column; ``keys``: lines in the legend alone), a line's ``zorder``,
``clip`` (false: drawn over the axes' edge), ``mew`` and ``legend_size`` (its marker's
size in the legend, opaque there) count there),
``layout`` (``"constrained"``; else ``margins``, figure fractions, if given; else tight),
``compress_level`` (the PNG's zlib level), ``sharex``, ``sharey``, ``height_ratios``
(of the rows) and ``caption`` (red, wrapped,
under the panels).
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["draw", "draw_png"]

#: matplotlib's line styles by the spec's dash names
_LINESTYLE = {"solid": "-", "dashed": "--", "dashdot": "-.", "dotted": ":"}
#: the caption's characters per line, and its height per line (figure fraction)
CAPTION_WIDTH, CAPTION_LINE = 90, 0.045


def _line(fig: Any, ax: Any, ln: dict[str, Any], colorbar: str) -> None:
    label = ln["name"] if ln["legend"] else "_nolegend_"
    if not (ln.get("scatter") or ln.get("values") is not None):
        ls = _LINESTYLE.get(ln["dash"], "-") if ln["lines"] else "none"
        extra = {k: ln[k] for k in ("zorder", "mew") if k in ln}
        ax.plot(ln["x"], ln["y"], color=ln["color"], alpha=ln["alpha"], lw=ln["width"], ls=ls,
                label=label, marker=ln["marker"] or None, ms=ln["size"], mec=ln["edge"],
                drawstyle="steps-post" if ln["step"] else "default", gid=ln["gid"] or None,
                clip_on=ln.get("clip", True), **extra)  # fmt: skip
        return
    kw: dict[str, Any] = {"s": ln["size"] ** 2, "marker": ln["marker"], "alpha": ln["alpha"],
                          "label": label, "gid": ln["gid"] or None}  # fmt: skip
    if ln.get("values") is None:
        ax.scatter(ln["x"], ln["y"], c=ln["color"], **kw)
    else:  # colour-mapped: its key beside the panel
        sc = ax.scatter(ln["x"], ln["y"], c=ln["values"], cmap=ln.get("cmap", "viridis"), **kw)
        fig.colorbar(sc, ax=ax, label=colorbar)


def _panel(fig: Any, ax: Any, p: dict[str, Any], below: bool) -> None:
    for im in p["images"]:
        ax.imshow(im["rgba"], origin="lower", aspect="auto", interpolation="nearest",
                  extent=(im["x"], im["x"] + im["dw"], im["y"], im["y"] + im["dh"]))  # fmt: skip
    for ln in p["lines"]:
        _line(fig, ax, ln, p.get("colorbar", ""))
    for t in p["texts"]:
        ax.text(t["x"], t["y"], t["text"], fontsize=8)
    ax.set_title(p["title"], **({"fontsize": p["title_pt"]} if "title_pt" in p else {}))
    ax.set_xlabel(p["xlabel"])
    ax.set_ylabel(p["ylabel"], **({"fontsize": p["ylabel_pt"]} if "ylabel_pt" in p else {}))
    if p["log"]:
        ax.set_yscale("log")
    ax.set_xlim(*p["xlim"])
    ax.set_ylim(*(p["ylim"][::-1] if p["inverted"] else p["ylim"]))
    if any(ln["legend"] for ln in p["lines"]) and not below:
        if any("legend_size" in ln for ln in p["lines"]):  # markers sized for the legend
            keys = _keys(p["lines"])
            ax.legend(list(keys.values()), list(keys), fontsize=p["legend_pt"])
        else:
            ax.legend(fontsize=p["legend_pt"])
    if p.get("grid"):
        ax.grid(alpha=p["grid"])
    if "yticks" in p:  # fixed ticks (a linear axis with its limits marked)
        from matplotlib.ticker import FixedLocator

        ax.yaxis.set_major_locator(FixedLocator(p["yticks"]))


def _keys(lines: list[dict[str, Any]]) -> dict[str, Any]:
    """Legend entries of ``lines``: each name once, in the order it first appears; a
    line's ``legend_size`` (markers) is its marker's size in the legend."""
    from matplotlib.lines import Line2D

    keys: dict[str, Any] = {}
    for ln in lines:
        if ln["legend"] and ln["name"] not in keys:
            ls = _LINESTYLE.get(ln["dash"], "-") if ln["lines"] else "none"
            keys[ln["name"]] = Line2D(
                [], [], color=ln["color"], ls=ls, lw=ln["width"], marker=ln["marker"] or None,
                ms=ln.get("legend_size", ln["size"]), mec=ln["edge"], mew=ln.get("mew"),
                alpha=None if "legend_size" in ln else ln["alpha"])  # fmt: skip
    return keys


def _legend_below(fig: Any, axes: Any, spec: dict[str, Any]) -> None:
    """One legend under the grid (of the first column's lines, if ``legend_columns``:
    one under each column, of its first panel's lines), then the spec's ``keys`` (marks
    that are no line: exits, stops)."""
    panels, size = spec["panels"], spec.get("legend_pt", 8.0)
    if spec.get("legend_columns"):
        for j in range(axes.shape[1]):
            top = [ln for p in panels if (p["row"], p["col"]) == (0, j) for ln in p["lines"]]
            keys = _keys(top + spec.get("keys", []))
            axes[-1, j].legend(list(keys.values()), list(keys), fontsize=size,
                               loc="upper center", ncol=1,
                               bbox_to_anchor=(0.5, -0.28))  # fmt: skip
        return
    if spec.get("legend_order") == "column":  # down each column of a heading, then across
        heads = list(dict.fromkeys(p.get("heading", "") for p in panels))
        panels = sorted(panels, key=lambda p: (heads.index(p.get("heading", "")), p["col"],
                                               p["row"]))  # fmt: skip
    cols = {p["col"] for p in panels} if spec.get("legend_columns") is None else {0}
    keys = _keys([ln for p in panels if p["col"] in cols for ln in p["lines"]]
                 + spec.get("keys", []))  # fmt: skip
    if keys:
        fig.legend(list(keys.values()), list(keys), loc="outside lower center",
                   ncol=min(spec.get("legend_ncol", len(keys)), len(keys)),
                   fontsize=size)  # fmt: skip


def draw(spec: dict[str, Any]) -> Any:
    """``spec`` (:mod:`.spec`) as a matplotlib ``Figure`` (not pyplot's: nothing to close),
    ready to save; :func:`draw_png` saves it."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    panels = spec["panels"]
    nrow = 1 + max(p["row"] for p in panels)
    ncol = 1 + max(p["col"] for p in panels)
    layout = spec.get("layout")  # "constrained", or tight around the caption
    fig = Figure(figsize=spec["size_in"], layout=layout)
    share = {"sharex": spec.get("sharex", False), "sharey": spec.get("sharey", False)}
    headings = [h for h in dict.fromkeys(p.get("heading", "") for p in panels) if h]
    if headings:  # rows under a heading: a subfigure each, of equal rows, stacked
        per = nrow // len(headings)
        subs = fig.subfigures(len(headings), 1, squeeze=False)[:, 0]
        axes = np.vstack([sub.subplots(per, ncol, squeeze=False, **share,
                                       height_ratios=spec.get("height_ratios") or None)
                          for sub in subs])  # fmt: skip
        for sub, h in zip(subs, headings, strict=True):
            sub.suptitle(h, fontsize=spec.get("heading_pt", 11.0), fontweight="bold")
    else:
        axes = fig.subplots(nrow, ncol, squeeze=False, **share,
                            height_ratios=spec.get("height_ratios") or None)  # fmt: skip
    used = np.zeros((nrow, ncol), dtype=bool)
    below = bool(spec.get("legend_below"))
    for p in panels:
        _panel(fig, axes[p["row"]][p["col"]], p, below)
        used[p["row"], p["col"]] = True
    for ax in axes[~used]:
        ax.set_visible(False)
    if below:  # one legend of the panels' lines, by name, under them
        _legend_below(fig, axes, spec)
    if spec["notes"]:  # colour keys (an image map's), one row under the panels
        keys = [Patch(color=n["color"], label=n["text"]) for n in spec["notes"]]
        fig.legend(handles=keys, loc="outside lower center", ncol=len(keys), fontsize=8)
    if spec.get("suptitle"):
        keys = (("suptitle_pt", "fontsize"), ("suptitle_color", "color"))
        style = {mpl: spec[key] for key, mpl in keys if key in spec}
        fig.suptitle(spec["suptitle"], **style)
    lines = textwrap.wrap(spec.get("caption", ""), CAPTION_WIDTH)
    if "margins" in spec and not layout:
        fig.subplots_adjust(**spec["margins"])
    elif not layout:
        fig.tight_layout(rect=(0, CAPTION_LINE * len(lines), 1, 1))
    if lines:
        fig.text(0.5, 0.01, "\n".join(lines), ha="center", va="bottom", fontsize=8,
                 color="tab:red")  # fmt: skip
    return fig


def draw_png(
    spec: dict[str, Any], path: str | Path, dpi: int = 100, metadata: dict[str, str] | None = None
) -> Path:
    """Draw ``spec`` (:mod:`.spec`) as a PNG at ``path`` with matplotlib (Agg); the file is
    complete or absent (written beside it, ``<name>.part``, then renamed).

    Parameters
    ----------
    spec : dict
        The figure: its panels laid out by their ``row`` and ``col``.
    path : str or Path
        The PNG written.
    dpi : int
        Pixels per inch (the spec's ``dpi`` if it has one); the figure is ``size_in``
        inches.
    metadata : dict of str, optional
        The PNG's text chunks (keyword: text).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    part = path.with_name(path.name + ".part")
    try:
        level = {"pil_kwargs": {"compress_level": spec["compress_level"]}} if (
            "compress_level" in spec) else {}  # fmt: skip
        draw(spec).savefig(part, dpi=spec.get("dpi", dpi), format="png",
                           metadata=dict(metadata or {}), **level)  # fmt: skip
        part.replace(path)
    finally:
        part.unlink(missing_ok=True)
    return path
