"""The report's K_c map: the default scenario over K_c, with and without the observer."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..runner.run import simulate
from ..scenarios.overrides import apply_overrides
from ..scenarios.scenario import load_scenario
from .figures import fmt, how_it_ends

#: the K_c grid of the map where the observer-fed loop works (default scenario)
KC_MAP = tuple(3.0 + 0.5 * i for i in range(19))  # 3 .. 12


def kc_map(fmu_dir: str | Path, ks: Sequence[float] = KC_MAP) -> list[dict[str, Any]]:
    """The default scenario over ``ks``: the passivity law fed by the observer, and with
    full-state feedback (no observer instance, so that only the loop can stop the run).
    One row per K_c: ``{"K_c": k, "observer": cell, "state": cell}``, a cell being the
    run's ``status``, ``outcome`` (:mod:`glider_cosim.runner.outcome`), its description, the
    settling time, the end time and the message."""
    rows = []
    for k in ks:
        row: dict[str, Any] = {"K_c": float(k)}
        for fb in ("observer", "state"):
            sc = apply_overrides(load_scenario("default"), {"controller.K_c": float(k)})
            sc.feedback, sc.observer = fb, fb == "observer"
            r = simulate(sc, None, fmu_dir=fmu_dir, build=False)
            m = r.metrics
            row[fb] = {
                "status": r.status,
                "outcome": m.get("outcome"),
                "text": how_it_ends(r),
                "settling_time_s": m.get("settling_time_s"),
                "rate_per_s": m.get("outcome_rate_per_s"),
                "end_time_s": float(r.data[-1, 0]) if len(r.data) else 0.0,
                "message": r.message,
            }
        rows.append(row)
    return rows


def smallest_settling(rows: Sequence[dict[str, Any]], fb: str) -> float | None:
    """The smallest K_c of the map from which every larger K_c settles too."""
    best = None
    for row in reversed(rows):
        if row[fb]["outcome"] != "settled":
            break
        best = row["K_c"]
    return best


def kc_map_markdown(
    rows: Sequence[dict[str, Any]], an: dict[str, Any] | None, metrics: str = "the docs' 'Metrics'"
) -> list[str]:
    """The report's K_c map section; ``metrics``: where the outcome is defined (a link)."""
    if not rows:
        return []
    lo_obs = lo_st = None
    if an is not None:
        lo_obs = an["stable_K_c"]["sampled_with_observer"][0]
        lo_st = an["stable_K_c"]["sampled"][0]
    k_obs, k_st = smallest_settling(rows, "observer"), smallest_settling(rows, "state")
    lines = [
        "## Where the observer-fed loop works over K_c",
        "",
        f"The default scenario (60 s, from theta_g = -35 deg, V = 0.2 m/s) with the passivity "
        f"law at K_c = {rows[0]['K_c']:g} to {rows[-1]['K_c']:g} in steps of "
        f"{rows[1]['K_c'] - rows[0]['K_c']:g}, fed by the observer, and with full-state "
        "feedback (no observer instance). Outcome from the trajectory "
        f"(`glider_cosim.runner.outcome`, {metrics}).",
        "",
        "| K_c | with the observer | full-state feedback |",
        "|---|---|---|",
    ]
    lines += [f"| {row['K_c']:g} | {row['observer']['text']} | {row['state']['text']} |"
              for row in rows]  # fmt: skip

    def limit(v):
        return "n/a" if v is None else f"{v:.2f}"

    lines += [
        "",
        "| | smallest K_c that settles (every larger one does too) | linear limit "
        "(`glider-cosim analyze`, sampled at 50 Hz) |",
        "|---|---|---|",
        f"| with the observer | {fmt(k_obs, 1, 1)} | {limit(lo_obs)} |",
        f"| full-state feedback | {fmt(k_st, 1, 1)} | {limit(lo_st)} |",
        "",
    ]
    by_k = {row["K_c"]: row for row in rows}
    reason = []
    if k_obs is not None and lo_obs is not None:
        below = [row for row in rows if lo_obs < row["K_c"] < k_obs]
        if below:
            row = below[-1]
            c = row["observer"]
            rate = c["rate_per_s"]
            decay = (
                f"its oscillation decays at {rate:+.3f} 1/s (half-life {math.log(2) / -rate:.0f} s)"
                if rate is not None and rate < 0
                else f"{c['text']}"
            )
            reason.append(
                f"between the linear limit and {k_obs:g} the sampled loop is stable but "
                f"barely damped: at K_c = {row['K_c']:g} {decay}, too slowly to stay in the "
                "band for the hold the outcome needs (max(10 s, 3 periods)) within 60 s"
            )
        first = by_k.get(k_obs)
        if first and first["state"]["outcome"] == "settled":
            d = first["observer"]["settling_time_s"] - first["state"]["settling_time_s"]
            reason.append(
                f"the observer's transient (it starts from its own equilibrium guess, not "
                f"the true -35 deg) costs {d:+.2f} s of settling at K_c = {k_obs:g} "
                f"({first['observer']['settling_time_s']:.2f} against "
                f"{first['state']['settling_time_s']:.2f} s)"
            )
        stops = [row for row in rows if row["observer"]["status"] != "ok"]
        if stops:
            row = stops[-1]
            reason.append(
                f"below the limit the observer's transient is what fails first: at K_c = "
                f"{row['K_c']:g} the observer-fed run {row['observer']['text']}, the "
                f"full-state one: {row['state']['text']}"
            )
    if reason:
        lines.append(
            f"Why K_c = {fmt(k_obs, 1, 1)} (observer) and {fmt(k_st, 1, 1)} (full state) "
            f"rather than the linear {limit(lo_obs)} and {limit(lo_st)}: " + "; ".join(reason) + "."
        )
        lines.append("")
    return lines
