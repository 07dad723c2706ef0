"""PNG plots of a run (angles in degrees, time in seconds)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .provenance import settings_text

_DEG = 180.0 / np.pi
#: how each marked event is drawn (colour, line style)
EVENT_STYLE = {
    "enable": ("tab:green", "--"),
    "takeover": ("tab:green", "-."),
    "stall": ("tab:red", "-"),
    "discard": ("tab:red", "--"),
    "error": ("darkred", ":"),
}
#: fixed margins (figure fractions) of the one-axes and the two-panel figures: a
#: constrained layout measured every text first and cost 40% of drawing (issue 31)
#: (the left one follows the y tick labels: :func:`_fit_left`)
SINGLE_MARGINS = {"left": 0.1, "right": 0.98, "bottom": 0.13, "top": 0.86}
PAIR_MARGINS = {"left": 0.1, "right": 0.98, "bottom": 0.09, "top": 0.9, "hspace": 0.1}
#: widths of DejaVu Sans characters, em (others: _EM_OTHER)
_EM = {**dict.fromkeys("0123456789", 0.636), "\N{MINUS SIGN}": 0.838, "-": 0.361, ".": 0.318}
_EM_OTHER = 0.7
#: zlib level of the PNGs: 1 writes in a third of the time of the default 6, files
#: about 1.5 times as large
PNG_COMPRESS_LEVEL = 1
#: the PNG text chunks that carry what a plot marks and which run it shows
META_EVENTS, META_SETTINGS = "glider-cosim:events", "glider-cosim:settings"
_BUILT: list | None = None  # the figures build_figures makes, with their PNGs' paths


def _title(result: Any, what: str) -> str:
    return f"{what} ({result.scenario.name})"


def _set_title(ax: Any, title: str) -> None:
    """The axes' title just above it (no ticks on top: the place matplotlib would find,
    without measuring the tick labels to find it, a quarter of the drawing time)."""
    ax.set_title(title, y=1.0)


def _events(result: Any) -> list[dict[str, Any]]:
    return list(result.metrics.get("events") or ())


def mark_events(axes: Any, events: list[dict[str, Any]], label: bool = True) -> None:
    """A vertical line per event (enable, takeover, stall, Discard) on each time axis;
    its ``gid`` is ``event:<kind>``; the first axis carries the legend labels."""
    for k, ax in enumerate(axes):
        for ev in events:
            color, ls = EVENT_STYLE.get(ev["kind"], ("k", ":"))
            ax.axvline(ev["time_s"], color=color, ls=ls, lw=1.1, alpha=0.9, zorder=4,
                       gid=f"event:{ev['kind']}",
                       label=f"{ev['label']}, t = {ev['time_s']:.2f} s"
                       if label and k == 0 else None)  # fmt: skip


def _fit_left(fig: Any) -> None:
    """The left margin wide enough for the widest y tick label, the ticks and the y
    label, from the labels' characters (no text is laid out: that is what made a
    constrained layout slow)."""
    em = plt.rcParams["ytick.labelsize"]
    em = fig.dpi / 72 * (em if isinstance(em, int | float) else plt.rcParams["font.size"])
    widest = 0.0
    for ax in fig.get_axes():
        lo, hi = sorted(ax.get_ylim())
        locs = [v for v in ax.yaxis.get_majorticklocs() if lo <= v <= hi]
        fmt = ax.yaxis.get_major_formatter()
        fmt.set_locs(locs)
        for text in (fmt(v) for v in locs):
            widest = max(widest, sum(_EM.get(c, _EM_OTHER) for c in text))
    # ticks, their pad and the label's (11 pt), the y label (1.2 em), a margin of 8 px
    need = widest * em + 11 * fig.dpi / 72 + 1.2 * em + 8
    for gs in {ax.get_subplotspec().get_gridspec() for ax in fig.get_axes()}:
        gs.update(left=min(0.3, need / (fig.get_figwidth() * fig.dpi)))


def _save(fig: Any, path: Path, result: Any) -> Path:
    """Finish ``fig`` (left margin, the run's settings as its subtitle) and note it, its
    PNG's path and text chunks for :func:`save_png` (:func:`build_figures`)."""
    _fit_left(fig)
    settings = settings_text(result.metrics)
    fig.suptitle(settings, fontsize=7.5, color="0.3")
    assert _BUILT is not None, "drawn by build_figures"
    _BUILT.append((fig, path, {META_EVENTS: json.dumps(_events(result)),
                               META_SETTINGS: settings}))  # fmt: skip
    return path


def save_png(fig: Any, path: Path, metadata: dict[str, str]) -> Path:
    """Draw ``fig`` into the PNG ``path`` with ``metadata`` as its text chunks; the file
    is complete or absent (written beside it, then renamed)."""
    part = path.with_name(path.name + ".part")
    try:
        fig.savefig(part, format="png", dpi=110, metadata=metadata,
                    pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL})  # fmt: skip
        part.replace(path)
    finally:
        part.unlink(missing_ok=True)
    return path


def read_png_record(path: Path) -> dict[str, Any]:
    """What a plot written here says about itself: ``{"events": [...], "settings": text}``
    (read back from the PNG's text chunks)."""
    from PIL import Image

    with Image.open(path) as im:
        text = dict(getattr(im, "text", {}) or im.info)
    return {"events": json.loads(text.get(META_EVENTS, "[]")),
            "settings": text.get(META_SETTINGS, "")}  # fmt: skip


def _glide_angle(result: Any, path: Path) -> Path:
    t = result.data[:, 0]
    fig, ax = _single_figure()
    ax.plot(t, result.column("plant.theta_g") * _DEG, lw=1.4, label="true")
    if "observer.theta_g_hat" in result.columns:
        ax.plot(t, result.column("observer.theta_g_hat") * _DEG, lw=1.0, ls="--",
                label="estimate")  # fmt: skip
    if result.metrics.get("theta_ge_rad") is not None:
        ax.axhline(result.metrics["theta_ge_rad"] * _DEG, color="k", ls=":", lw=0.8,
                   label="equilibrium")  # fmt: skip
    _set_title(ax, _title(result, "Glide angle"))
    ax.set(xlabel="time [s]", ylabel="theta_g [deg]")
    mark_events([ax], _events(result))
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=7)
    return _save(fig, path, result)


def _pitch(result: Any, path: Path) -> Path:
    """Values on top; below, measured and estimated pitch minus the true one, so the
    measurement is visible even when its noise is far smaller than the transient."""
    t = result.data[:, 0]
    cols = result.columns
    # a swapped-in plant may lack one of them: draw what was recorded
    true = result.column("plant.theta") * _DEG if "plant.theta" in cols else None
    meas = result.column("plant.theta_meas") * _DEG if "plant.theta_meas" in cols else None
    est = (
        result.column("observer.theta_hat") * _DEG
        if "observer.theta_hat" in result.columns
        else None
    )
    fig, (ax, ax2) = _pair_figure()
    std = float(result.scenario.parameters.get("plant", {}).get("noise_std", 0.0)) * _DEG
    # without noise the measurement is the true pitch: one series, named both ways
    same = meas is not None and true is not None and np.array_equal(meas, true)
    if meas is not None and not same:
        ax.plot(t, meas, ls="none", marker=".", ms=1.2, alpha=0.3, color="tab:gray", zorder=1,
                label=f"measured (samples, noise std {std:.2g} deg)")  # fmt: skip
    if true is not None:  # drawn over the measured samples
        ax.plot(t, true, lw=1.6, color="tab:blue", zorder=3,
                label="true = measured (noise std 0 deg)" if same else "true")  # fmt: skip
    if est is not None:
        ax.plot(t, est, lw=1.0, ls="--", color="tab:orange", zorder=3.5, label="estimate")
    # below: differences to the true pitch, or to the measured one without it
    ref, ref_name = (true, "true") if true is not None else (meas, "measured")
    if meas is not None and true is not None and not same:
        ax2.plot(t, meas - true, ls="none", marker=".", ms=1.2, alpha=0.3, color="tab:gray",
                 zorder=1, label="measured - true")  # fmt: skip
    if est is not None:
        ax2.plot(t, est - ref, lw=1.0, color="tab:orange", zorder=3,
                 label=f"estimate - {ref_name}")  # fmt: skip
    return _finish_pair(fig, (ax, ax2), _title(result, "Pitch"), "theta", path, result)


#: blank figures made ahead (:func:`make_ahead`), taken by the next figures drawn
_AHEAD: dict[str, list[tuple[Any, Any]]] = {"single": [], "pair": []}


def _new_figure(kind: str) -> tuple[Any, Any]:
    if kind == "pair":  # two panels sharing their time axis: values above, differences below
        return plt.subplots(2, 1, figsize=(7, 5.2), sharex=True,
                            gridspec_kw={**PAIR_MARGINS, "height_ratios": (2, 1)})  # fmt: skip
    return plt.subplots(figsize=(7, 3.6), gridspec_kw=SINGLE_MARGINS)


def _single_figure() -> tuple[Any, Any]:
    """A figure of one panel (made ahead if one is waiting)."""
    return _AHEAD["single"].pop() if _AHEAD["single"] else _new_figure("single")


def _pair_figure() -> tuple[Any, tuple[Any, Any]]:
    """A figure of two panels sharing their time axis: values above, differences below
    (made ahead if one is waiting)."""
    return _AHEAD["pair"].pop() if _AHEAD["pair"] else _new_figure("pair")


def make_ahead(kind: str) -> None:
    """Make a blank figure of ``kind`` (``"single"`` or ``"pair"``) for the next figure of
    that kind: what creating the figure and its axes costs (about 5 and 9 ms) is then paid
    before the data is there (the drawing process, while the run runs)."""
    _AHEAD[kind].append(_new_figure(kind))


def discard_ahead() -> None:
    """Close the blank figures :func:`make_ahead` made and no plot took."""
    for kind in _AHEAD:
        while _AHEAD[kind]:
            plt.close(_AHEAD[kind].pop()[0])


def _finish_pair(
    fig: Any, axes: tuple[Any, Any], title: str, name: str, path: Path, result: Any
) -> Path:
    """Values above (``name`` in deg), differences below; events marked on both; grids,
    legends where labelled."""
    ax, ax2 = axes
    _set_title(ax, title)
    ax.set(ylabel=f"{name} [deg]")
    ax2.set(xlabel="time [s]", ylabel="difference [deg]")
    mark_events(axes, _events(result))
    for a in axes:
        a.grid(alpha=0.3)
        if a.get_legend_handles_labels()[0]:
            a.legend(loc="best", fontsize=7, markerscale=4)
    return _save(fig, path, result)


def _tail(result: Any, path: Path) -> Path:
    """The command as the held (zero-order-hold) steps it is, the servo as a line; below,
    command minus servo angle (the servo's lag)."""
    t = result.data[:, 0]
    cmd = result.column("controller.delta_cmd") * _DEG
    servo = result.column("plant.delta") * _DEG if "plant.delta" in result.columns else None
    fig, (ax, ax2) = _pair_figure()
    if servo is not None:  # a swapped-in plant may have no servo output
        ax.plot(t, servo, lw=2.4, alpha=0.45, color="k", zorder=2,
                label="servo angle (sampled)")  # fmt: skip
        ax2.plot(t, cmd - servo, lw=1.0, color="tab:purple", label="command - servo")
    # the command on top, thin and dashed: the servo's wide line stays visible under it
    ax.step(t, cmd, where="post", lw=1.1, ls="--", color="tab:red", zorder=3,
            label="command (held)")  # fmt: skip
    return _finish_pair(fig, (ax, ax2), _title(result, "Tail angle"), "delta", path, result)


def _speed(result: Any, path: Path) -> Path:
    t = result.data[:, 0]
    fig, ax = _single_figure()
    ax.plot(t, result.column("plant.V"), lw=1.4, label="true")
    if "observer.V_hat" in result.columns:
        ax.plot(t, result.column("observer.V_hat"), lw=1.0, ls="--", label="estimate")
    if result.metrics.get("V_e_m_s") is not None:  # as glide_angle.png marks theta_ge
        ax.axhline(result.metrics["V_e_m_s"], color="k", ls=":", lw=0.8, label="equilibrium")
    _set_title(ax, _title(result, "Speed"))
    ax.set(xlabel="time [s]", ylabel="V [m/s]")
    mark_events([ax], _events(result))
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=7)
    return _save(fig, path, result)


def _depth(result: Any, path: Path) -> Path:
    fig, ax = _single_figure()
    x, z, t = result.column("plant.x"), result.column("plant.z"), result.data[:, 0]
    ax.plot(x, z, lw=1.2)
    for ev in _events(result):  # not a time axis: the events as points on the path
        color, _ = EVENT_STYLE.get(ev["kind"], ("k", ":"))
        k = min(int(np.searchsorted(t, ev["time_s"] - 1e-9)), len(t) - 1)
        marker = {"enable": "o", "takeover": "D"}.get(ev["kind"], "X")
        ax.plot([x[k]], [z[k]], marker=marker, ms=7, color=color, ls="none", zorder=4,
                gid=f"event:{ev['kind']}",
                label=f"{ev['label']}, t = {ev['time_s']:.2f} s")  # fmt: skip
    ax.invert_yaxis()
    _set_title(ax, _title(result, "Depth profile"))
    ax.set(xlabel="x [m]", ylabel="depth z [m]")
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best", fontsize=7)
    return _save(fig, path, result)


def write_plots(result: Any, out: Path, keep: list | None = None) -> dict[str, Path]:
    """Write the glide-angle, pitch, tail-angle, speed and depth-profile PNGs to ``out``
    (those whose columns were recorded). Each marks the run's events and names its
    scenario and overrides; both are also in the PNG's text chunks
    (:func:`read_png_record`). ``keep``: a list that gets the figures, left open."""
    files = {}
    for fig, path, metadata in build_figures(result, out):
        files[path.stem] = save_png(fig, path, metadata)
        if keep is not None:
            keep.append(fig)
        else:
            plt.close(fig)
    return files


#: the run's plots, in the order they are drawn and shown: (name (its PNG is
#: ``<name>.png``), its figure's kind (one panel or two), the columns it needs, the
#: function that builds it into that PNG's path)
PLOTS = (
    ("glide_angle", "single", ("plant.theta_g",), _glide_angle),
    ("pitch", "pair", ("plant.theta_meas",), _pitch),
    ("tail_angle", "pair", ("controller.delta_cmd",), _tail),
    ("speed", "single", ("plant.V",), _speed),
    ("depth", "single", ("plant.x", "plant.z"), _depth),
)
#: each plot's figure kind, by name
FIGURE_KIND = {name: kind for name, kind, _, _ in PLOTS}


def build_figures(
    result: Any, out: Path, names: Sequence[str] | None = None
) -> list[tuple[Any, Path, dict[str, str]]]:
    """The figures of :func:`write_plots` (of ``names`` only, if given), not drawn yet:
    ``(figure, its PNG's path in out, its PNG's text chunks)`` each, for
    :func:`save_png`."""
    global _BUILT
    _BUILT = []
    cols = set(result.columns)
    try:
        for name, _, needs, fn in PLOTS:
            if (names is None or name in names) and all(c in cols for c in needs):
                fn(result, out / f"{name}.png")
        return _BUILT
    finally:
        _BUILT = None
