"""`glider-cosim report`: every figure's scenario, the analysis, the agreement section."""

from __future__ import annotations

import json
import math
import re

import pytest

from glider_cosim.analysis import analyze
from glider_cosim.report import FIGURES, apply_overrides, build_report, passivity_gain
from glider_cosim.scenario import load_scenario

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def report(fmu_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    an = analyze()
    path = build_report(out, fmu_dir, analysis=lambda: an, progress=False, roa_grid=(3, 3))
    return path.read_text(), an, out


def _section(text: str, title: str) -> str:
    start = text.index(f"## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start : end if end >= 0 else len(text)]


def test_report_is_written_with_figures_tables_and_findings(report):
    text, _, out = report
    for fig in FIGURES:
        assert (out / f"{fig.key}.png").stat().st_size > 10_000
        assert f"![{fig.key}]({fig.key}.png)" in text
        for run in fig.runs:
            assert f"| {run.label} |" in _section(text, fig.title)
    assert (out / "communication_step.png").exists()
    m = re.search(r"against the monolithic sampled loop .*they agree to ([0-9.e+-]+) \(max", text)
    assert m and float(m.group(1)) <= 1e-6
    assert "identical" not in text
    assert "## Where we agree with the paper, and where we do not" in text
    assert "**Disagreement**: the literal Sec. 5.3 protocol" in text
    assert "| passivity K_c = 10 (ours) | ok | settled |" in text
    assert "**Disagreement**: the paper's K_c = 2" in text
    assert "the Schur complement of Sec. 3.2 is [[-1.26, 10.19]" in text
    assert re.search(r"stable K_c range, full-state, continuous time: \(5\.2\d, unbounded\)", text)
    assert "tau_s = 12.59 s" in text
    assert (out / "fig8.png").stat().st_size > 10_000
    sec = _section(text, "Sec. 5.2 / Fig. 8: open loop with the tail held")
    assert "The steady glide with u held is stable up to u = 2.57 deg" in sec
    assert re.search(r"^\| 1 \| 2\.57 \| 2\.3\d \|$", sec, re.M)
    assert "**Disagreement** with Fig. 8 at K_udelta = 1" in sec
    assert "**Implication for the paper's unstated K_udelta**" in sec


def test_region_of_attraction_map_is_drawn_from_a_dask_sweep(report):
    text, _, out = report
    assert (out / "roa.png").stat().st_size > 10_000
    sec = _section(text, "Region of attraction")
    assert "from a 3 x 3 grid" in sec
    rows = {m.group(1): [int(v) for v in m.group(2, 3)] for m in re.finditer(
        r"^\| (passivity K_c = \d+|open loop)[^|]* \| (\d+) \| (\d+) \|", sec, re.M)}  # fmt: skip
    assert rows["passivity K_c = 2"] == [9, 0]  # linearly unstable: nothing settles
    assert rows["passivity K_c = 10"][1] >= 1
    for key in ("kc10", "kc2", "open"):
        assert (out / "roa" / key / "sweep.csv").exists()


def test_every_gain_called_settling_lies_in_the_sampled_stable_range(report):
    """And every passivity run outside that range is reported as not settling."""
    text, an, _ = report
    inside = outside = 0
    for fig in FIGURES:
        sec = _section(text, fig.title)
        for run in fig.runs:
            sc = apply_overrides(load_scenario(run.scenario), run.overrides)
            k = passivity_gain(sc)
            if k is None:
                continue
            key = "sampled_with_observer" if sc.feedback == "observer" else "sampled"
            lo = an["stable_K_c"][key][0]
            row = re.search(rf"^\| {re.escape(run.label)} \| (\w+) \| ([^|]+) \|", sec, re.M)
            outcome = row.group(2).strip()
            if k > lo:
                inside += 1
                assert outcome == "settled", (fig.key, run.label, outcome)
            else:
                outside += 1
                assert outcome != "settled", (fig.key, run.label, outcome)
    assert inside >= 3 and outside >= 3
    assert "**Inconsistent with the analysis**" not in text


def test_scenario_notes_agree_with_the_analysis(report):
    _, an, out = report
    notes = load_scenario("default").notes
    rng = an["stable_K_c"]
    for key in ("sampled_with_observer", "sampled", "continuous"):
        assert f"{rng[key][0]:.2f}" in notes, key
    held = json.loads((out / "report.json").read_text())["held_tail"]
    notes = load_scenario("sec53-protocol").notes
    for key in ("u_linear_rad", "u_release_rad"):
        assert f"{math.degrees(held[key]):.2f} deg" in notes, key
    for tail in (15, 30, 45):
        assert f"K_udelta={held['k_star']:g}" in load_scenario(f"sec52-tail{tail}").notes
