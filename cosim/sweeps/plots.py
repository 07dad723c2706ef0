"""Plots of a sweep's results (PNG beside ``sweep.csv``)."""

from __future__ import annotations

import csv
import math
from pathlib import Path


def write_plots(path: Path, out: Path) -> list[Path]:
    """Plots that apply to the swept parameters (PNG beside the results)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return []

    def num(r: dict, k: str) -> float:
        try:
            return float(r[k])
        except (KeyError, TypeError, ValueError):
            return math.nan

    params = [k for k in rows[0] if "." in k]
    files = []
    if "controller.K_c" in params:
        ok = [r for r in rows if r["status"] == "ok" and r["settling_time_s"] not in ("", None)]
        fig, ax = plt.subplots(figsize=(6, 4))
        sc = ax.scatter([num(r, "control_effort") for r in ok],
                        [num(r, "settling_time_s") for r in ok],
                        c=[num(r, "controller.K_c") for r in ok], cmap="viridis")  # fmt: skip
        fig.colorbar(sc, label="K_c")
        ax.set(xlabel="control effort [rad s]", ylabel="settling time [s]",
               title="Settling time against control effort (Sec. 3.3 trade-off)")  # fmt: skip
        ax.grid(alpha=0.3)
        fig.tight_layout()
        files.append(out / "settling_vs_effort.png")
        fig.savefig(files[-1], dpi=100)
        plt.close(fig)
    if len(params) >= 2:
        a, b = params[:2]
        good = [r["status"] == "ok" and r["settling_time_s"] not in ("", None) for r in rows]
        fig, ax = plt.subplots(figsize=(6, 4))
        for flag, colour, label in ((True, "tab:green", "settles"),
                                    (False, "tab:red", "does not settle / fails")):  # fmt: skip
            pts = [(num(r, a), num(r, b)) for r, g in zip(rows, good, strict=True) if g == flag]
            if pts:
                ax.scatter(*zip(*pts, strict=True), c=colour, label=label, s=18)
        ax.set(xlabel=a, ylabel=b, title="Stability boundary")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        files.append(out / "stability_boundary.png")
        fig.savefig(files[-1], dpi=100)
        plt.close(fig)
    if "plant.noise_std" in params:
        pts = [(num(r, "plant.noise_std"), num(r, "estimation_rms_rad")) for r in rows]
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.scatter(*zip(*pts, strict=True), s=18)
        ax.set(xlabel="sensor noise std [rad]", ylabel="estimation error RMS [rad]",
               title="Estimation error against sensor noise")  # fmt: skip
        ax.grid(alpha=0.3)
        fig.tight_layout()
        files.append(out / "estimation_vs_noise.png")
        fig.savefig(files[-1], dpi=100)
        plt.close(fig)
    return files


__all__ = ["write_plots"]
