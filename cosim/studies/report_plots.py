"""The report's paper figures as specs (:mod:`glider_cosim.figures.spec`): a paper
figure's panels (Figs. 2-6) and Figs. 11-20's small multiples, each drawn to its PNG."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..figures.mpl import draw_png
from ..figures.spec import exit_marks, line, panel, set_limits, share_x, sheet
from ..runner.run import RunResult
from .figures import DEG, Figure, Run, how_it_ends


def _bounded(r: RunResult) -> bool:
    """A run that stays bounded: it ran to the end and does not diverge."""
    return r.status == "ok" and r.metrics.get("outcome") != "diverging"


def _keys(clipped: bool, stopped: bool, marked: bool) -> list[dict[str, Any]]:
    """Legend entries for the marks a figure uses (spec lines of no data)."""
    keys = []
    if clipped:
        keys.append(line([], [], "leaves the axes (clipped there)", marker="^", color="0.3",
                         size=7.0, width=1.5))  # fmt: skip
    if stopped:
        keys.append({**line([], [], "the run stops (V or V_hat stalls or diverges)",
                            marker="x", color="0.3", size=7.0, width=1.5), "mew": 2.0})  # fmt: skip
    if marked:
        keys.append(line([], [], "the controller takes over", dash="dashdot", color="0.3",
                         width=0.8))  # fmt: skip
    return keys


def figure_spec(fig: Figure, results: Sequence[tuple[Run, RunResult]]) -> dict[str, Any]:
    """A report figure as a spec (:mod:`glider_cosim.figures.spec`): one panel per
    (column, group); y-limits of a row from the runs that stay bounded (shared by the
    row's panels); a run leaving them is clipped and marked (a triangle where it leaves,
    a cross where a stopped run ends, both in the legend)."""
    import textwrap

    from matplotlib import rcParams
    from matplotlib.colors import to_hex

    groups = list(dict.fromkeys(run.group for run, _ in results)) if fig.by_group else [""]
    nrow, ncol = len(fig.panels), len(groups)
    width = 8.0 if ncol == 1 else 4.3 * ncol
    colours = [to_hex(c) for c in rcParams["axes.prop_cycle"].by_key()["color"]]
    colour = {run.label: colours[i % len(colours)] for i, (run, _) in enumerate(results)}
    clipped = stopped = marked = False
    panels = []
    for i, (col, ylabel) in enumerate(fig.panels):
        series = [(run, r, r.data[:, 0], r.column(col) * DEG) for run, r in results
                  if col in r.columns and len(r.data)]  # fmt: skip
        for j, g in enumerate(groups):
            mine = [y for run, r, _, y in series if _bounded(r)
                    and (fig.share_y or not fig.by_group or run.group == g)]  # fmt: skip
            lim = None
            if mine:
                lo = min(float(np.min(y)) for y in mine)
                hi = max(float(np.max(y)) for y in mine)
                pad = 0.08 * max(hi - lo, 1.0)
                lim = (lo - pad, hi + pad)
            lines = []
            for run, r, t, y in series:
                if fig.by_group and run.group != g:
                    continue
                c = colour[run.label]
                notes = []
                if lim is not None:
                    marks = exit_marks(t, y, lim[0], lim[1], c, 8.0)
                    lines += marks
                    clipped |= len(marks) > 0
                if r.status != "ok":
                    notes.append(f"stopped at {t[-1]:.1f} s")
                    y_end = y[-1] if lim is None else min(max(y[-1], lim[0]), lim[1])
                    lines.append({**line([t[-1]], [y_end], marker="x", color=c, size=8.0,
                                         width=1.5), "lines": True, "mew": 2.0, "clip": False,
                                  "zorder": 5})  # fmt: skip
                for ev in r.metrics.get("events") or ():  # the takeover, in the run's colour
                    if ev["kind"] in ("takeover", "enable"):
                        lines.append(line([ev["time_s"]], [0.0], color=c, dash="dashdot",
                                          width=0.8, alpha=0.8, span="x",
                                          gid=f"event:{ev['kind']}"))  # fmt: skip
                        marked = True
                label = run.label + (f" ({'; '.join(notes)})" if notes else "")
                lines.append(line(t, y, label if i == 0 else "", color=c))
                stopped |= r.status != "ok"
            if col in ("plant.theta_g", "observer.theta_g_hat"):
                th = next((r.metrics.get("theta_ge_rad") for _, r in results), None)
                if th is not None:
                    lines.append(line([0.0], [th * DEG], "equilibrium", color="k",
                                      dash="dotted", width=0.8, span="y"))  # fmt: skip
            p = panel(lines, title=g if i == 0 and fig.by_group else "", row=i, grid=0.3,
                      xlabel="time [s]" if i == nrow - 1 else "",
                      ylabel=ylabel if j == 0 else "")  # fmt: skip
            if lim is not None:  # the equilibrium, drawn after them, does not widen them
                set_limits(p, ylim=lim)
            p.update(
                col=j,
                **({"ylabel_pt": 8.0} if j == 0 else {}),
                **({"title_pt": 9.0} if p["title"] else {}),
            )
            panels.append(p)
    share_x(panels)
    title = "\n".join(textwrap.wrap(fig.title, int(width * 13)))
    return {**sheet(panels, (width, 2.6 * nrow + 0.6)), "title": title, "suptitle": title,
            "suptitle_pt": 10.0, "layout": "constrained", "sharex": True,
            "legend_below": True, "legend_columns": fig.by_group, "legend_pt": 7.0,
            "legend_ncol": 3, "keys": _keys(clipped, stopped, marked)}  # fmt: skip


def plot_figure(fig: Figure, results: Sequence[tuple[Run, RunResult]], out: Path) -> Path:
    """``<key>.png``: :func:`figure_spec` drawn."""
    return draw_png(figure_spec(fig, results), out / f"{fig.key}.png")


def _feedback(r: RunResult) -> str:
    return "observer" if r.scenario.feedback == "observer" else "full-state"


#: fixed axes of Figs. 11-20 (deg): the angles, the tail command (linear, to +-100 deg,
#: ticks every 45 deg)
SEC53_ANGLES = (-70.0, 40.0)


SEC53_TAIL = 100.0
SEC53_TAIL_TICKS = (-90.0, -45.0, 0.0, 45.0, 90.0)


#: Figs. 11-20 start at 20 s: before the takeover (31.1 s) every run is the same 2 deg hold
SEC53_FROM = 20.0


def _sec53_panels(run: Run, r: RunResult, row: int, col: int, xlim: tuple[float, float],
                  last: bool) -> list[dict[str, Any]]:  # fmt: skip
    """One run's two panels of Figs. 11-20: the angles over the tail command."""
    t = r.data[:, 0]
    lo, hi = SEC53_ANGLES
    top = []
    for c, label, lw, colour in (("plant.theta_g", "glide angle", 1.3, "tab:blue"),
                                 ("plant.theta", "pitch", 0.8, "tab:orange")):  # fmt: skip
        y = r.column(c) * DEG
        top.append(line(t, np.clip(y, lo, hi), label, color=colour, width=lw))
        top += exit_marks(t, y, lo, hi, colour, 7.0)
    th = r.metrics.get("theta_ge_rad")
    if th is not None:
        top.append(line([0.0], [th * DEG], "equilibrium", color="k", dash="dotted",
                        width=0.8, span="y"))  # fmt: skip
    bottom = [line(t, r.column("controller.delta_cmd") * DEG, "tail command",
                   color="tab:green")]  # fmt: skip
    dmax = float(r.scenario.parameters.get("controller", {}).get("delta_max", math.pi / 2))
    bottom += [line([0.0], [sign * dmax * DEG], color="#666666", dash="dotted", width=0.8,
                    span="y") for sign in (1, -1)]  # fmt: skip
    for ev in r.metrics.get("events") or ():
        if ev["kind"] == "takeover":
            for lines, name in ((top, "takeover"), (bottom, "")):
                lines.append(line([ev["time_s"]], [0.0], name, color="k", dash="dashdot",
                                  width=0.9, span="x", gid="event:takeover"))  # fmt: skip
    if r.status != "ok":
        y_end = float(np.clip(r.column("plant.theta_g")[-1] * DEG, lo, hi))
        top.append({**line([t[-1]], [y_end], "stop", marker="x", color="#ff0000", size=9.0,
                           width=1.5, gid="event:stop"),
                    "lines": True, "mew": 2.0, "clip": False, "zorder": 6})  # fmt: skip
        bottom.append(line([t[-1]], [0.0], "stop (tail panel)", color="#ff0000", width=0.8,
                           span="x", gid="event:stop"))  # fmt: skip
    first = {"ylabel_pt": 8.0} if col == 0 else {}
    p_top = panel(top, title=f"{run.label}\n{_feedback(r)} feedback: {how_it_ends(r)}", row=row,
                  ylabel="angle [deg]" if col == 0 else "", grid=0.3)  # fmt: skip
    p_bottom = panel(bottom, row=row + 1, grid=0.3, xlabel="time [s]" if last else "",
                     ylabel="tail cmd [deg]" if col == 0 else "")  # fmt: skip
    set_limits(p_top, xlim=xlim, ylim=(lo, hi))
    set_limits(p_bottom, xlim=xlim, ylim=(-SEC53_TAIL, SEC53_TAIL))
    p_top.update(col=col, title_pt=8.5, **first)
    p_bottom.update(col=col, yticks=list(SEC53_TAIL_TICKS), **first)
    return [p_top, p_bottom]


def sec53_spec(fig: Figure, results: Sequence[tuple[Run, RunResult]]) -> dict[str, Any]:
    """Figs. 11-20 as small multiples, a spec (:mod:`glider_cosim.figures.spec`): one row
    per law family, one column per run; per run the glide angle and pitch over the tail
    command, on the same fixed axes in every panel (angles -70..40 deg, clipped with a
    triangle where a run leaves them; the tail on a linear scale to +-100 deg, its +-90
    deg limit dotted). Each heading names the run, its feedback and how it ends; the
    takeover (dash-dot) and a stop (cross) are marked."""
    groups = list(dict.fromkeys(run.group for run, _ in results))
    ncol = max(sum(1 for run, _ in results if run.group == g) for g in groups)
    stop = max(float(r.data[-1, 0]) for _, r in results)
    start = SEC53_FROM if stop > SEC53_FROM + 10 else 0.0
    panels = []
    for gi, g in enumerate(groups):
        runs = [(run, r) for run, r in results if run.group == g]
        pairs = [_sec53_panels(run, r, 2 * gi, j, (start, stop), gi == len(groups) - 1)
                 for j, (run, r) in enumerate(runs)]  # fmt: skip
        for k in (0, 1):  # row by row, as the page reads a grid
            panels += [{**pair[k], "heading": g} for pair in pairs]
    title = (fig.title + f"\nfrom t = {start:g} s (before the takeover every run is the same "
             "2 deg hold); dash-dot: the controller takes over at 1 m depth;\ntriangle: the "
             "curve leaves the axes (clipped there); cross and red line: the run stops (V or "
             "V_hat stalls or diverges)")  # fmt: skip
    return {**sheet(panels, (4.6 * ncol, 4.4 * len(groups) + 0.8)), "title": title,
            "suptitle": title, "suptitle_pt": 10.0, "layout": "constrained", "sharex": True,
            "height_ratios": [2.0, 1.3], "legend_below": True, "legend_order": "column",
            "dpi": 90}  # fmt: skip


def plot_sec53(fig: Figure, results: Sequence[tuple[Run, RunResult]], out: Path) -> Path:
    """``fig11-20.png``: :func:`sec53_spec` drawn."""
    return draw_png(sec53_spec(fig, results), out / f"{fig.key}.png")
