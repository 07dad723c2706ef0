"""PNG plots of a run (angles in degrees, time in seconds)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

_DEG = 180.0 / np.pi


def _title(result: Any, what: str) -> str:
    return f"{what} ({result.scenario.name})"


def _save(fig: Any, path: Path) -> Path:
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _glide_angle(result: Any, out: Path) -> Path:
    t = result.data[:, 0]
    fig, ax = plt.subplots(figsize=(7, 3.6), layout="constrained")
    ax.plot(t, result.column("plant.theta_g") * _DEG, lw=1.4, label="true")
    if "observer.theta_g_hat" in result.columns:
        ax.plot(t, result.column("observer.theta_g_hat") * _DEG, lw=1.0, ls="--",
                label="estimate")  # fmt: skip
    if result.metrics.get("theta_ge_rad") is not None:
        ax.axhline(result.metrics["theta_ge_rad"] * _DEG, color="k", ls=":", lw=0.8,
                   label="equilibrium")  # fmt: skip
    ax.set(title=_title(result, "Glide angle"), xlabel="time [s]", ylabel="theta_g [deg]")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    return _save(fig, out / "glide_angle.png")


def _pitch(result: Any, out: Path) -> Path:
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
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7, 5.2), sharex=True, layout="constrained",
                                  height_ratios=(2, 1))  # fmt: skip
    std = float(result.scenario.parameters.get("plant", {}).get("noise_std", 0.0)) * _DEG
    if meas is not None:
        ax.plot(t, meas, ls="none", marker=".", ms=2.5, alpha=0.45, color="tab:gray",
                label=f"measured (samples, noise std {std:.2g} deg)")  # fmt: skip
    if true is not None:
        ax.plot(t, true, lw=1.4, color="tab:blue", label="true")
    if est is not None:
        ax.plot(t, est, lw=1.0, ls="--", color="tab:orange", label="estimate")
    # below: differences to the true pitch, or to the measured one without it
    ref, ref_name = (true, "true") if true is not None else (meas, "measured")
    if meas is not None and true is not None:
        ax2.plot(t, meas - true, ls="none", marker=".", ms=2.5, alpha=0.45, color="tab:gray",
                 label="measured - true")  # fmt: skip
    if est is not None:
        ax2.plot(t, est - ref, lw=1.0, color="tab:orange", label=f"estimate - {ref_name}")
    return _finish_pair(fig, (ax, ax2), _title(result, "Pitch"), "theta", out / "pitch.png")


def _finish_pair(fig: Any, axes: tuple[Any, Any], title: str, name: str, path: Path) -> Path:
    """Values above (``name`` in deg), differences below; grids, legends where labelled."""
    ax, ax2 = axes
    ax.set(title=title, ylabel=f"{name} [deg]")
    ax2.set(xlabel="time [s]", ylabel="difference [deg]")
    for a in axes:
        a.grid(alpha=0.3)
        if a.get_legend_handles_labels()[0]:
            a.legend(loc="best", fontsize=8)
    return _save(fig, path)


def _tail(result: Any, out: Path) -> Path:
    """The command as the held (zero-order-hold) steps it is, the servo as a line; below,
    command minus servo angle (the servo's lag)."""
    t = result.data[:, 0]
    cmd = result.column("controller.delta_cmd") * _DEG
    servo = result.column("plant.delta") * _DEG if "plant.delta" in result.columns else None
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7, 5.2), sharex=True, layout="constrained",
                                  height_ratios=(2, 1))  # fmt: skip
    ax.step(t, cmd, where="post", lw=2.2, alpha=0.5, color="tab:red", label="command (held)")
    if servo is not None:  # a swapped-in plant may have no servo output
        ax.plot(t, servo, lw=1.0, color="k", label="servo angle (sampled)")
        ax2.plot(t, cmd - servo, lw=1.0, color="tab:purple", label="command - servo")
    return _finish_pair(fig, (ax, ax2), _title(result, "Tail angle"), "delta",
                        out / "tail_angle.png")  # fmt: skip


def _speed(result: Any, out: Path) -> Path:
    t = result.data[:, 0]
    fig, ax = plt.subplots(figsize=(7, 3.6), layout="constrained")
    ax.plot(t, result.column("plant.V"), lw=1.4, label="true")
    if "observer.V_hat" in result.columns:
        ax.plot(t, result.column("observer.V_hat"), lw=1.0, ls="--", label="estimate")
    ax.set(title=_title(result, "Speed"), xlabel="time [s]", ylabel="V [m/s]")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    return _save(fig, out / "speed.png")


def _depth(result: Any, out: Path) -> Path:
    fig, ax = plt.subplots(figsize=(7, 3.6), layout="constrained")
    ax.plot(result.column("plant.x"), result.column("plant.z"), lw=1.2)
    ax.invert_yaxis()
    ax.set(title=_title(result, "Depth profile"), xlabel="x [m]", ylabel="depth z [m]")
    ax.grid(alpha=0.3)
    return _save(fig, out / "depth.png")


def write_plots(result: Any, out: Path) -> dict[str, Path]:
    """Write the glide-angle, pitch, tail-angle, speed and depth-profile PNGs to ``out``
    (those whose columns were recorded)."""
    cols = set(result.columns)
    files = {}
    for stem, needs, fn in (
        ("glide_angle", ("plant.theta_g",), _glide_angle),
        ("pitch", ("plant.theta_meas",), _pitch),
        ("tail_angle", ("controller.delta_cmd",), _tail),
        ("speed", ("plant.V",), _speed),
        ("depth", ("plant.x", "plant.z"), _depth),
    ):
        if all(c in cols for c in needs):
            files[stem] = fn(result, out)
    return files
