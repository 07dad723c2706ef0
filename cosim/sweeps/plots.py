"""Plots of a sweep's results (PNG beside ``sweep.csv``): figure specs
(:mod:`glider_cosim.figures.spec`) drawn by :mod:`glider_cosim.figures.mpl`."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

from ..figures.mpl import draw_png
from ..figures.spec import line, panel, sheet
from ..fmus.variables import unit_of_target, with_unit

#: a sweep figure's size, inches
SIZE_IN = (6.0, 4.0)


def _short(param: str, params: list[str]) -> str:
    """``controller.K_c`` as ``K_c`` unless another swept parameter has that name."""
    name = param.rpartition(".")[2]
    return name if sum(p.rpartition(".")[2] == name for p in params) == 1 else param


def _value(text: str, param: str = "") -> str:
    """A swept value as ``%g``, followed by the unit of ``param`` (if it has one)."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        return str(text)
    return with_unit(param, value) if param else f"{value:g}"


def _axis(param: str) -> str:
    """An axis label of a swept parameter: ``plant.V_0 [m/s]``, ``controller.K_c [1]``
    (a parameter that is not of our FMUs: its name alone)."""
    unit = unit_of_target(param)
    return param if unit is None else f"{param} [{unit}]"


def _is_number(text: object) -> bool:
    try:
        float(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return True


def runs_named(rows: list[dict], params: list[str], most: int = 6) -> str:
    """The swept values of ``rows``, e.g. ``K_c = 4, 6`` (one parameter) or
    ``K_c = 4, V_0 = 0.2; K_c = 6, V_0 = 0.3``, in the order of the values (not of
    ``sweep.csv``, which is the order the runs ended); at most ``most`` runs, then ``...``."""

    def key(r: dict) -> tuple:
        return tuple((0, float(v), "") if _is_number(v) else (1, 0.0, str(v))
                     for v in (r.get(p) for p in params))  # fmt: skip

    rows = sorted(rows, key=key)
    if len(params) == 1:
        text = ", ".join(_value(r.get(params[0]), params[0]) for r in rows[:most])
        text = f"{_short(params[0], params)} = {text}"
    else:
        text = "; ".join(
            ", ".join(f"{_short(p, params)} = {_value(r.get(p), p)}" for p in params)
            for r in rows[:most]
        )
    return text + (", ..." if len(rows) > most else "")


def missing_runs_note(rows: list[dict], shown: list[bool], params: list[str], what: str) -> str:
    """One line counting the runs a plot does not show, by reason, naming their values:
    ``2 of 5 runs did not settle (K_c = 4, 6); 1 of 5 runs failed (K_c = -1)``. Empty
    when every run is shown.

    Parameters
    ----------
    rows : list of dict
        The sweep's rows (``sweep.csv``).
    shown : list of bool
        Whether each row is drawn.
    params : list of str
        The swept parameters (``instance.name``).
    what : str
        Why an ``ok`` run is not drawn, e.g. ``did not settle``.
    """
    n = len(rows)
    hidden = [r for r, s in zip(rows, shown, strict=True) if not s]
    parts = []
    for reason, group in (
        (what, [r for r in hidden if r.get("status") == "ok"]),
        ("failed", [r for r in hidden if r.get("status") != "ok"]),
    ):
        if group:
            runs = "run" if n == 1 else "runs"
            parts.append(f"{len(group)} of {n} {runs} {reason} ({runs_named(group, params)})")
    return "; ".join(parts)


def _num(r: dict, k: str) -> float:
    try:
        return float(r[k])
    except (KeyError, TypeError, ValueError):
        return math.nan


def _scatter(pts: list[tuple[float, float]], **kw: Any) -> dict[str, Any]:
    """Markers at ``pts`` (a spec line, :func:`~glider_cosim.figures.spec.line`)."""
    xs, ys = zip(*pts, strict=True) if pts else ((), ())
    return {**line(xs, ys, marker="o", **kw), "scatter": True}


def sweep_specs(rows: list[dict]) -> list[tuple[str, dict[str, Any]]]:
    """The plots that apply to the swept parameters of ``rows`` (``sweep.csv``), as
    ``(file name, figure spec)``: each figure built once, drawn by :func:`write_plots`."""
    if not rows:
        return []
    params = [k for k in rows[0] if "." in k]
    specs = []
    if "controller.K_c" in params:
        shown = [
            r["status"] == "ok"
            and math.isfinite(_num(r, "settling_time_s"))
            and math.isfinite(_num(r, "control_effort"))
            for r in rows
        ]
        ok = [r for r, s in zip(rows, shown, strict=True) if s]
        pts = [(_num(r, "control_effort"), _num(r, "settling_time_s")) for r in ok]
        dots = _scatter(pts, values=[_num(r, "controller.K_c") for r in ok], gid="runs")
        p = panel([dots], xlabel="control effort [rad s]", ylabel="settling time [s]",
                  title="Settling time against control effort (Sec. 3.3 trade-off)",
                  grid=0.3, colorbar=_axis("controller.K_c"))  # fmt: skip
        note = missing_runs_note(rows, shown, params, "did not settle")
        specs.append(("settling_vs_effort.png", sheet([p], SIZE_IN, note)))
    if len(params) >= 2:
        a, b = params[:2]
        good = [r["status"] == "ok" and r["settling_time_s"] not in ("", None) for r in rows]
        lines = []
        for flag, colour, label in ((True, "tab:green", "settles"),
                                    (False, "tab:red", "does not settle / fails")):  # fmt: skip
            pts = [(_num(r, a), _num(r, b)) for r, g in zip(rows, good, strict=True) if g == flag]
            if pts:
                lines.append(_scatter(pts, color=colour, size=math.sqrt(18),
                                      name=f"{label} ({len(pts)} of {len(rows)})"))  # fmt: skip
        p = panel(lines, xlabel=_axis(a), ylabel=_axis(b), title="Stability boundary",
                  grid=0.3, legend_pt=8.0)  # fmt: skip
        specs.append(("stability_boundary.png", sheet([p], SIZE_IN)))
    if "plant.noise_std" in params:
        pts = [(_num(r, "plant.noise_std"), _num(r, "estimation_rms_rad")) for r in rows]
        shown = [
            r["status"] == "ok" and all(map(math.isfinite, p))
            for r, p in zip(rows, pts, strict=True)
        ]
        drawn = [p for p, s in zip(pts, shown, strict=True) if s]
        p = panel([_scatter(drawn, size=math.sqrt(18), gid="runs")] if drawn else [],
                  xlabel="sensor noise std [rad]", ylabel="estimation error RMS [rad]",
                  title="Estimation error against sensor noise", grid=0.3)  # fmt: skip
        note = missing_runs_note(rows, shown, params, "have no estimation error")
        specs.append(("estimation_vs_noise.png", sheet([p], SIZE_IN, note)))
    return specs


def write_plots(path: Path, out: Path) -> list[Path]:
    """Plots that apply to the swept parameters (PNG beside the results), each drawn from
    its spec (:func:`sweep_specs`) by :func:`~glider_cosim.figures.mpl.draw_png`."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return [draw_png(spec, out / name) for name, spec in sweep_specs(rows)]


__all__ = ["missing_runs_note", "runs_named", "sweep_specs", "write_plots"]
