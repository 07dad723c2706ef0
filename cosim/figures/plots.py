"""A run's plots (angles in degrees, time in seconds), each defined once as a spec
(:mod:`.spec`): :mod:`.mpl` draws it as the PNG and :mod:`.pages` as the zoomable
``plots.html``, so both show the same lines, labels and limits.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..fmus.variables import overrides_words, short
from .spec import COLORS, SIZES, figure, line, panel

__all__ = ["COLORS", "EVENT_STYLE", "PLOTS", "SIZES", "PlotError", "build_specs",
           "event_lines", "figure", "line", "panel", "read_png_record", "settings_text",
           "write_plots"]  # fmt: skip

_DEG = 180.0 / np.pi
#: how each marked event is drawn (colour, line style)
EVENT_STYLE = {
    "enable": ("tab:green", "dashed"),
    "takeover": ("tab:green", "dashdot"),
    "stall": ("tab:red", "solid"),
    "discard": ("tab:red", "dashed"),
    "error": ("darkred", "dotted"),
}
#: the size (points) of a sample's dot in a legend (drawn 1.2 pt in the panel: too small
#: and faint to see there)
LEGEND_DOT = 6.0
#: the PNG text chunks that carry what a plot marks and which run it shows
META_EVENTS, META_SETTINGS = "glider-cosim:events", "glider-cosim:settings"


class PlotError(OSError):
    """A run's PNG plots could not be written (its results and metrics.json are kept)."""


def settings_text(metrics: dict[str, Any]) -> str:
    """``"scenario default; controller.K_c=6, plant.V_0=0.3 m/s, --step 0.01"``: what a
    plot's subtitle says (each override's number with its unit)."""
    run = metrics.get("run") or {}
    parts = overrides_words(run.get("overrides", {}), units=True)
    parts += [k if v is True else f"{k} {short(v)}" for k, v in run.get("options", {}).items()]
    text = f"scenario {metrics.get('scenario', run.get('scenario', '?'))}"
    return text + ("; " + ", ".join(parts) if parts else "; no overrides")


def _run_figure(result: Any, kind: str, panels: Sequence[dict[str, Any]]) -> dict[str, Any]:
    return figure(kind, panels, settings_text(result.metrics))


def _title(result: Any, what: str) -> str:
    return f"{what} ({result.scenario.name})"


def _events(result: Any) -> list[dict[str, Any]]:
    return list(result.metrics.get("events") or ())


def event_lines(events: list[dict[str, Any]], label: bool = True) -> list[dict[str, Any]]:
    """A vertical line per event (enable, takeover, stall, Discard), ``gid``
    ``event:<kind>``; named in the legend if ``label``."""
    out = []
    for ev in events:
        color, dash = EVENT_STYLE.get(ev["kind"], ("k", "dotted"))
        name = f"{ev['label']}, t = {ev['time_s']:.2f} s" if label else ""
        out.append(line([ev["time_s"]], [0.0], name, color=color, dash=dash, width=1.1,
                         alpha=0.9, span="x", gid=f"event:{ev['kind']}"))  # fmt: skip
    return out


def _glide_angle(result: Any) -> dict[str, Any]:
    t = result.data[:, 0]
    lines = [line(t, result.column("plant.theta_g") * _DEG, "true", width=1.4)]
    if "observer.theta_g_hat" in result.columns:
        lines.append(line(t, result.column("observer.theta_g_hat") * _DEG, "estimate",
                          color="tab:orange", dash="dashed"))  # fmt: skip
    if result.metrics.get("theta_ge_rad") is not None:
        lines.append(line([0.0], [result.metrics["theta_ge_rad"] * _DEG], "equilibrium",
                          color="k", dash="dotted", width=0.8, span="y"))  # fmt: skip
    lines += event_lines(_events(result))
    return _run_figure(result, "single", [panel(lines, title=_title(result, "Glide angle"),
                                           xlabel="time [s]", ylabel="theta_g [deg]")])  # fmt: skip


def _pitch(result: Any) -> dict[str, Any]:
    """Values on top; below, measured and estimated pitch minus the true one, so the
    measurement is visible even when its noise is far smaller than the transient."""
    t = result.data[:, 0]
    cols = result.columns
    # a swapped-in plant may lack one of them: draw what was recorded
    true = result.column("plant.theta") * _DEG if "plant.theta" in cols else None
    # the pitch the observer reads: the plant's sensor, or what a scenario's
    # [connections] feed it instead (an added component's output, e.g. noise.theta_out)
    src = result.scenario.connections.get("observer.theta_meas", "plant.theta_meas")
    src = src if src in cols else "plant.theta_meas"
    meas = result.column(src) * _DEG if src in cols else None
    est = result.column("observer.theta_hat") * _DEG if "observer.theta_hat" in cols else None
    std = float(result.scenario.parameters.get("plant", {}).get("noise_std", 0.0)) * _DEG
    name = "measured" if src == "plant.theta_meas" else src
    # without noise the measurement is the true pitch: one series, named both ways
    same = meas is not None and true is not None and np.array_equal(meas, true)
    top, below = [], []
    if meas is not None and not same:
        what = f"noise std {std:.2g} deg" if src == "plant.theta_meas" else "the observer's input"
        top.append(line(t, meas, f"{name} (samples, {what})", color="tab:gray", alpha=0.3,
                        marker=".", size=1.2) | {"legend_size": LEGEND_DOT})  # fmt: skip
    if true is not None:  # drawn over the measured samples
        top.append(line(t, true, f"true = {name} (noise std 0 deg)" if same else "true",
                        width=1.6))  # fmt: skip
    if est is not None:
        top.append(line(t, est, "estimate", color="tab:orange", dash="dashed"))
    # below: differences to the true pitch, or to the measured one without it
    ref, ref_name = (true, "true") if true is not None else (meas, name)
    if meas is not None and true is not None and not same:
        below.append(line(t, meas - true, f"{name} - true", color="tab:gray", alpha=0.3,
                          marker=".", size=1.2) | {"legend_size": LEGEND_DOT})  # fmt: skip
    if est is not None:
        below.append(line(t, est - ref, f"estimate - {ref_name}", color="tab:orange"))
    return _pair(result, top, below, _title(result, "Pitch"), "theta")


def _pair(
    result: Any, top: list[dict[str, Any]], below: list[dict[str, Any]], title: str, name: str
) -> dict[str, Any]:
    """Values above (``name`` in deg), differences below, one time axis; events marked
    on both (named in the upper legend)."""
    events = _events(result)
    above = panel(top + event_lines(events), title=title, ylabel=f"{name} [deg]")
    under = panel(below + event_lines(events, label=False), xlabel="time [s]",
                  ylabel="difference [deg]", row=1)  # fmt: skip
    shared = [min(above["xlim"][0], under["xlim"][0]), max(above["xlim"][1], under["xlim"][1])]
    for p in (above, under):  # one time axis: the wider limits, the spans across them
        p["xlim"] = list(shared)
        for ln in p["lines"]:
            if ln["span"] == "y":
                ln["x"] = np.array(shared)
    return _run_figure(result, "pair", [above, under])


def _tail(result: Any) -> dict[str, Any]:
    """The command as the held (zero-order-hold) steps it is, the servo as a line; below,
    command minus servo angle (the servo's lag)."""
    t = result.data[:, 0]
    cmd = result.column("controller.delta_cmd") * _DEG
    servo = result.column("plant.delta") * _DEG if "plant.delta" in result.columns else None
    top, below = [], []
    if servo is not None:  # a swapped-in plant may have no servo output
        top.append(line(t, servo, "servo angle (sampled)", color="k", width=2.4, alpha=0.45))
        below.append(line(t, cmd - servo, "command - servo", color="tab:purple"))
    # the command on top, thin and dashed: the servo's wide line stays visible under it
    top.append(line(t, cmd, "command (held)", color="tab:red", width=1.1, dash="dashed",
                    step=True))  # fmt: skip
    return _pair(result, top, below, _title(result, "Tail angle"), "delta")


def _speed(result: Any) -> dict[str, Any]:
    t = result.data[:, 0]
    lines = [line(t, result.column("plant.V"), "true", width=1.4)]
    if "observer.V_hat" in result.columns:
        lines.append(line(t, result.column("observer.V_hat"), "estimate", color="tab:orange",
                          dash="dashed"))  # fmt: skip
    if result.metrics.get("V_e_m_s") is not None:  # as glide_angle.png marks theta_ge
        lines.append(line([0.0], [result.metrics["V_e_m_s"]], "equilibrium", color="k",
                          dash="dotted", width=0.8, span="y"))  # fmt: skip
    lines += event_lines(_events(result))
    return _run_figure(result, "single", [panel(lines, title=_title(result, "Speed"),
                                           xlabel="time [s]", ylabel="V [m/s]")])  # fmt: skip


def _depth(result: Any) -> dict[str, Any]:
    x, z, t = result.column("plant.x"), result.column("plant.z"), result.data[:, 0]
    lines = [line(x, z, width=1.2)]
    for ev in _events(result):  # not a time axis: the events as points on the path
        color, _ = EVENT_STYLE.get(ev["kind"], ("k", "dotted"))
        k = min(int(np.searchsorted(t, ev["time_s"] - 1e-9)), len(t) - 1)
        marker = {"enable": "o", "takeover": "D"}.get(ev["kind"], "X")
        name = f"{ev['label']}, t = {ev['time_s']:.2f} s"
        lines.append(line([x[k]], [z[k]], name, color=color, marker=marker, size=7.0,
                          gid=f"event:{ev['kind']}"))  # fmt: skip
    return _run_figure(result, "single", [panel(lines, title=_title(result, "Depth profile"),
                                           xlabel="x [m]", ylabel="depth z [m]",
                                           inverted=True)])  # fmt: skip


#: the run's plots, in the order they are drawn and shown: (name (its PNG is
#: ``<name>.png``), the columns it needs, the function that makes its spec)
PLOTS = (
    ("glide_angle", ("plant.theta_g",), _glide_angle),
    ("pitch", ("plant.theta_meas",), _pitch),
    ("tail_angle", ("controller.delta_cmd",), _tail),
    ("speed", ("plant.V",), _speed),
    ("depth", ("plant.x", "plant.z"), _depth),
)


def build_specs(
    result: Any, out: Path, names: Sequence[str] | None = None
) -> list[tuple[dict[str, Any], Path, dict[str, str]]]:
    """The specs of :func:`write_plots` (of ``names`` only, if given), those whose
    columns were recorded: ``(spec, its PNG's path in out, its PNG's text chunks)``."""
    cols = set(result.columns)
    meta = {META_EVENTS: json.dumps(_events(result)),
            META_SETTINGS: settings_text(result.metrics)}  # fmt: skip
    return [(fn(result), Path(out) / f"{name}.png", meta) for name, needs, fn in PLOTS
            if (names is None or name in names) and all(c in cols for c in needs)]  # fmt: skip


def write_plots(result: Any, out: Path, keep: list | None = None) -> dict[str, Path]:
    """Write the glide-angle, pitch, tail-angle, speed and depth-profile PNGs to ``out``
    (those whose columns were recorded). Each marks the run's events and names its
    scenario and overrides; both are also in the PNG's text chunks
    (:func:`read_png_record`). ``keep``: a list that gets the specs drawn."""
    from .mpl import draw_png

    files = {}
    for spec, path, metadata in build_specs(result, out):
        files[path.stem] = draw_png(spec, path, metadata=metadata)
        if keep is not None:
            keep.append(spec)
    return files


def read_png_record(path: Path) -> dict[str, Any]:
    """What a plot written here says about itself: ``{"events": [...], "settings": text}``
    (read back from the PNG's text chunks)."""
    from PIL import Image  # Pillow: matplotlib's own dependency, which writes them

    with Image.open(path) as im:
        text = dict(getattr(im, "text", {}) or im.info)
    return {"events": json.loads(text.get(META_EVENTS, "[]")),
            "settings": text.get(META_SETTINGS, "")}  # fmt: skip
