"""Region of attraction: the outcome of the loop over a grid of initial glide angles and
speeds, run as a Dask sweep (local cluster by default), for the default gain K_c = 10,
the paper's K_c = 2 and the open loop (full-state feedback, as in the analysis of the
sampled loop).

Each start is classified from its trajectory (:mod:`glider_cosim.runner.outcome`): settled, not
settled, limit cycle, diverging, or stopped (a stall: V fell to the model's limit).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

from ..figures.mpl import draw_png
from ..figures.spec import line, panel, sheet
from ..runner.outcome import (
    DIVERGING,
    LIMIT_CYCLE,
    NOT_SETTLED,
    SETTLED,
    STOPPED,
    TUMBLING,
)
from ..scenarios.overrides import apply_overrides
from ..scenarios.scenario import Scenario, load_scenario

DEG = 180.0 / math.pi
THETA_RANGE_DEG = (-165.0, 165.0)  # initial glide angle, deg (any attitude, no duplicates)
V_RANGE = (0.02, 1.0)  # initial speed, m/s
CATEGORIES = (SETTLED, NOT_SETTLED, LIMIT_CYCLE, DIVERGING, TUMBLING, STOPPED)
COLOURS = ("tab:green", "yellowgreen", "tab:orange", "tab:red", "tab:purple", "0.25")


class RoaError(ValueError):
    """A region-of-attraction request is malformed (grid size)."""


@dataclass(frozen=True)
class RoaCase:
    """One controller of the map: label, shipped scenario, overrides, linear verdict key."""

    key: str
    label: str
    scenario: str
    overrides: tuple[tuple[str, float], ...]
    K_c: float | None  # None: open loop


CASES = (
    RoaCase("kc10", "passivity K_c = 10 (default)", "fig3-4-kc", (("controller.K_c", 10.0),), 10.0),
    RoaCase("kc2", "passivity K_c = 2 (paper)", "fig3-4-kc", (("controller.K_c", 2.0),), 2.0),
    RoaCase("open", "open loop (tail at 0)", "fig2-open-loop", (), None),
)


@dataclass
class RoaMap:
    """Outcomes on the grid: ``outcome[i, j]`` for ``theta_g0[i]`` [rad], ``V0[j]`` [m/s]."""

    case: RoaCase
    theta_g0: np.ndarray
    V0: np.ndarray
    outcome: np.ndarray  # object array of outcome names
    stop_time: float
    runs_per_s: float

    def count(self, what: str) -> int:
        return int(np.sum(self.outcome == what))


def parse_grid(text: str) -> tuple[int, int]:
    """``"9x7"`` -> (9 glide angles, 7 speeds); each at least 2.

    Raises
    ------
    RoaError
        If the text is not ``NxM`` with integers N, M >= 2.
    """
    parts = text.lower().split("x")
    try:
        n, m = (int(p) for p in parts)
    except ValueError:
        raise RoaError(f"grid {text!r} is invalid: expected NxM, e.g. 9x7") from None
    if n < 2 or m < 2:
        raise RoaError(f"grid {text!r} is invalid: expected N, M >= 2")
    return n, m


def _scenario(case: RoaCase) -> Scenario:

    return apply_overrides(load_scenario(case.scenario), dict(case.overrides))


def run_roa(
    out: Path,
    fmu_dir: Path,
    grid: tuple[int, int],
    client: Any,
    cases=CASES,
    progress: Callable[[str], None] | None = None,
) -> list[RoaMap]:
    """Sweep every case over the grid on the Dask ``client`` (results in
    ``out/<case>/sweep.csv``, recomputed each time); ``progress`` is told each case as it
    starts."""
    from ..sweeps.sweep import ParamSpec, expand, run_sweep

    n, m = grid
    th = np.radians(np.linspace(*THETA_RANGE_DEG, n))
    vs = np.linspace(*V_RANGE, m)
    maps = []
    for case in cases:
        if progress is not None:
            progress(f"the region-of-attraction map: {case.key}, {n * m} runs")
        sc = _scenario(case)
        specs = [ParamSpec("plant.theta_g_0", tuple(float(x) for x in th)),
                 ParamSpec("plant.V_0", tuple(float(v) for v in vs))]  # fmt: skip
        runs = expand(specs, sc, fmu_dir)
        res = run_sweep(sc, runs, out / case.key, client, fmu_dir, restart=True)
        outcome = np.full((n, m), "", dtype=object)
        with open(res.path, newline="") as f:
            for row in csv.DictReader(f):
                i = int(np.argmin(np.abs(th - float(row["plant.theta_g_0"]))))
                j = int(np.argmin(np.abs(vs - float(row["plant.V_0"]))))
                outcome[i, j] = row["outcome"] or (STOPPED if row["status"] != "ok" else "")
        maps.append(RoaMap(case, th, vs, outcome, sc.stop_time, res.runs_per_s))
    return maps


def settled_box(mp: RoaMap, p: GliderParams | None = None) -> tuple[float, float] | None:
    """Half-widths (|d theta_g0| [rad], |d V0| [m/s]) of the largest box of grid points
    around the equilibrium, growing one grid step at a time on each side, in which every
    start settles; None if the grid point nearest the equilibrium does not settle."""
    e = equilibrium(p or GliderParams())
    i0 = int(np.argmin(np.abs(mp.theta_g0 - e.theta_g)))
    j0 = int(np.argmin(np.abs(mp.V0 - e.V)))
    if mp.outcome[i0, j0] != SETTLED:
        return None
    k = 0
    n, m = mp.outcome.shape
    while True:
        a, b, c, d = i0 - k - 1, i0 + k + 1, j0 - k - 1, j0 + k + 1
        if a < 0 or c < 0 or b >= n or d >= m:
            break
        if not np.all(mp.outcome[a : b + 1, c : d + 1] == SETTLED):
            break
        k += 1
    dth = max(abs(mp.theta_g0[i0 + s] - e.theta_g) for s in (-k, k) if 0 <= i0 + s < n)
    dv = max(abs(mp.V0[j0 + s] - e.V) for s in (-k, k) if 0 <= j0 + s < m)
    return float(dth), float(dv)


def _exceptions(mp: RoaMap, limit: int = 6) -> str:
    """The starts that do not settle, as text (at most ``limit``)."""
    items = [
        f"{mp.outcome[i, j]} from {mp.theta_g0[i] * DEG:.0f} deg, {mp.V0[j]:.2f} m/s"
        for i in range(mp.outcome.shape[0])
        for j in range(mp.outcome.shape[1])
        if mp.outcome[i, j] != SETTLED
    ]
    more = f" and {len(items) - limit} more" if len(items) > limit else ""
    return "; ".join(items[:limit]) + more


def _cell_edges(mp: RoaMap) -> tuple[float, float, float, float]:
    """The image extent (V_0 [m/s], theta_g_0 [deg]) whose cells are centred on the grid
    points (the grid is uniform: :func:`run_roa`'s linspace)."""

    def edges(v: np.ndarray) -> tuple[float, float]:
        half = (v[-1] - v[0]) / (len(v) - 1) / 2 if len(v) > 1 else 0.5 * max(abs(v[0]), 1.0)
        return float(v[0] - half), float(v[-1] + half)

    return (*edges(mp.V0), *edges(mp.theta_g0 * DEG))


def _image(mp: RoaMap) -> dict[str, Any]:
    """The outcome map as a spec image: RGBA cells (rows from the lowest theta_g_0), the
    outcome's name of each (``report.html``'s hover), the extent of :func:`_cell_edges`."""
    from matplotlib.colors import ListedColormap, Normalize

    code = np.vectorize(lambda o: CATEGORIES.index(o) if o in CATEGORIES else np.nan,
                        otypes=[float])(mp.outcome)  # fmt: skip
    norm = Normalize(vmin=-0.5, vmax=len(CATEGORIES) - 0.5)
    rgba = ListedColormap(COLOURS)(norm(np.ma.masked_invalid(code)), bytes=True)
    names = np.array([[CATEGORIES[int(v)] if np.isfinite(v) else "" for v in row]
                      for row in code], dtype=object)  # fmt: skip
    x0, x1, y0, y1 = _cell_edges(mp)
    return {"rgba": rgba, "value": names, "x": x0, "y": y0, "dw": x1 - x0, "dh": y1 - y0}


def roa_spec(maps: list[RoaMap]) -> dict[str, Any]:
    """The region-of-attraction figure as a spec (:mod:`glider_cosim.figures.spec`): one
    panel per case, the outcome of each start, the equilibrium (star) and the Sec. 3.3
    start (circle); drawn to ``roa.png`` and in ``report.html`` alike."""
    from matplotlib.colors import to_hex

    e = equilibrium(GliderParams())
    panels = []
    for k, mp in enumerate(maps):
        mark = {"color": "#ffffff", "edge": "k", "width": 1.5}  # width: the page's marker edge
        marks = [line([e.V], [e.theta_g * DEG], marker="*", size=14.0, **mark),
                 line([0.2], [-35.0], marker="o", size=7.0, **mark)]  # fmt: skip
        p = panel(marks, title=f"{mp.case.label}\n{mp.stop_time:g} s runs",
                  xlabel="initial speed V_0 [m/s]",
                  ylabel="" if k else "initial glide angle theta_g_0 [deg]")  # fmt: skip
        x0, x1, y0, y1 = _cell_edges(mp)
        p.update(col=k, images=[_image(mp)], xlim=[x0, x1], ylim=[y0, y1], title_pt=9.0)
        panels.append(p)
    labels = [*CATEGORIES[:-1], "stopped (stall)"]
    title = ("Region of attraction (full-state feedback, alpha_0 = 1 deg; star: "
             "equilibrium, circle: the Sec. 3.3 start)")  # fmt: skip
    return {**sheet(panels, (4.3 * len(maps), 4.4)), "title": title, "suptitle": title,
            "suptitle_pt": 10.0, "layout": "constrained", "sharey": True,
            "notes": [{"text": t, "color": to_hex(c)} for t, c in
                      zip(labels, COLOURS, strict=True)]}  # fmt: skip


def plot_roa(maps: list[RoaMap], out: Path) -> Path:
    """``roa.png``: :func:`roa_spec` drawn."""
    return draw_png(roa_spec(maps), out / "roa.png")


def roa_markdown(maps: list[RoaMap], png: Path, an: dict[str, Any] | None) -> list[str]:
    """The report section: counts per outcome, the settled box, linear against nonlinear."""
    n, m = maps[0].outcome.shape
    lines = [
        "## Region of attraction",
        "",
        f"Outcome of the loop from a {n} x {m} grid of initial glide angles "
        f"({THETA_RANGE_DEG[0]:g} to {THETA_RANGE_DEG[1]:g} deg) and speeds "
        f"({V_RANGE[0]:g} to {V_RANGE[1]:g} m/s), alpha_0 = 1 deg, full-state feedback; run "
        "as a Dask sweep (`glider_cosim.studies.roa`, local cluster), each start classified from "
        "its trajectory (the glide angle modulo 360 deg: a start that loops over and then glides "
        "steadily has settled; runs of each controller as long as its shipped scenario). "
        "`glider-cosim report --roa-grid 21x15` draws a finer map.",
        "",
        f"![roa]({png.name})",
        "",
        "| controller | starts | " + " | ".join(CATEGORIES) + " | runs/s |",
        "|---|---|" + "---|" * (len(CATEGORIES) + 1),
    ]
    for mp in maps:
        counts = " | ".join(str(mp.count(c)) for c in CATEGORIES)
        lines.append(f"| {mp.case.label} | {mp.outcome.size} | {counts} | {mp.runs_per_s:.1f} |")
    lines.append("")
    rng = (an or {}).get("stable_K_c", {}).get("sampled", [None, None])
    lo = rng[0]
    ol = (an or {}).get("open_loop_eigenvalues")
    for mp in maps:
        k = mp.case.K_c
        if k is None:
            stable = ol is not None and max(re for re, _ in ol) < 0
            verdict = "stable" if stable else "unstable"
        else:
            stable = lo is not None and k > lo
            verdict = f"{'stable' if stable else 'unstable'} (sampled stable range K_c > {lo:.2f})"
        box = settled_box(mp)
        n_set = mp.count(SETTLED)
        others = ", ".join(f"{mp.count(c)} {c}" for c in CATEGORIES[1:] if mp.count(c))
        where = _exceptions(mp)
        if stable and n_set == mp.outcome.size:
            text = (
                f"linearly {verdict}, and every start on the grid settles: the local result "
                "predicts the outcome far beyond the neighbourhood it is derived for"
            )
        elif stable and box is not None:
            text = (
                f"linearly {verdict}: every start within {box[0] * DEG:.1f} deg and "
                f"{box[1]:.3f} m/s of the equilibrium settles, as the linear result predicts; "
                f"{n_set} of {mp.outcome.size} starts settle on the grid ({others}); it does "
                f"not predict the others ({where})"
            )
        elif stable:
            text = (
                f"linearly {verdict}, but the start nearest the equilibrium does not settle "
                f"within the run ({others}; {where})"
            )
        elif n_set == 0:
            text = (
                f"linearly {verdict}, and no start settles ({others}): the linear result "
                "predicts that the loop does not settle anywhere on the grid (not what it "
                "does instead)"
            )
        else:
            text = (
                f"linearly {verdict}, yet {n_set} starts settle ({others}): the linear "
                "result does not predict those"
            )
        lines.append(f"- {mp.case.label}: {text}.")
    lines.append("")
    return lines
