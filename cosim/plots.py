"""PNG plots of a run (angles in degrees, time in seconds)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

# (file stem, title, y label, [(column, label, scale)])
_DEG = 180.0 / np.pi
PLOTS = (
    ("glide_angle", "Glide angle", "theta_g [deg]",
     [("plant.theta_g", "true", _DEG), ("observer.theta_g_hat", "estimate", _DEG)]),
    ("pitch", "Pitch", "theta [deg]",
     [("plant.theta_meas", "measured", _DEG), ("plant.theta", "true", _DEG),
      ("observer.theta_hat", "estimate", _DEG)]),
    ("tail_angle", "Tail angle", "delta [deg]",
     [("controller.delta_cmd", "command", _DEG), ("plant.delta", "actual (servo)", _DEG)]),
    ("speed", "Speed", "V [m/s]",
     [("plant.V", "true", 1.0), ("observer.V_hat", "estimate", 1.0)]),
)  # fmt: skip


def write_plots(result: Any, out: Path) -> dict[str, Path]:
    """Write the glide-angle, pitch, tail-angle, speed and depth-profile PNGs to ``out``."""
    files = {}
    cols = result.columns
    t = result.data[:, 0]
    for stem, title, ylabel, series in PLOTS:
        present = [(c, lab, s) for c, lab, s in series if c in cols]
        if not present:
            continue
        fig, ax = plt.subplots(figsize=(7, 3.6))
        for c, lab, s in present:
            ax.plot(t, result.column(c) * s, label=lab, lw=1.2)
        if stem == "glide_angle" and result.metrics.get("theta_ge_rad") is not None:
            ax.axhline(
                result.metrics["theta_ge_rad"] * _DEG,
                color="k",
                ls=":",
                lw=0.8,
                label="equilibrium",
            )
        ax.set(title=f"{title} ({result.scenario.name})", xlabel="time [s]", ylabel=ylabel)
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
        fig.tight_layout()
        files[stem] = out / f"{stem}.png"
        fig.savefig(files[stem], dpi=110)
        plt.close(fig)
    if "plant.x" in cols and "plant.z" in cols:
        fig, ax = plt.subplots(figsize=(7, 3.6))
        ax.plot(result.column("plant.x"), result.column("plant.z"), lw=1.2)
        ax.invert_yaxis()
        ax.set(
            title=f"Depth profile ({result.scenario.name})", xlabel="x [m]", ylabel="depth z [m]"
        )
        ax.grid(alpha=0.3)
        fig.tight_layout()
        files["depth"] = out / "depth.png"
        fig.savefig(files["depth"], dpi=110)
        plt.close(fig)
    return files
