"""`glider-cosim report`: every figure's scenario, the analysis, the agreement section."""

from __future__ import annotations

import json
import math
import re

import pytest
from system_tools import require_tool

from glider_cosim.scenarios.overrides import apply_overrides
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.studies.analysis import analyze
from glider_cosim.studies.figures import FIGURES, passivity_gain
from glider_cosim.studies.kc_map import kc_map
from glider_cosim.studies.report import build_report

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


def test_kc_map_table_agrees_with_runs(report, fmu_dir):
    """The K_c map's table, its smallest settling gains and limits, checked against runs
    made here (three gains of the grid) and against the analysis."""
    text, an, _ = report
    sec = _section(text, "Where the observer-fed loop works over K_c")
    rows = {float(m.group(1)): (m.group(2).strip(), m.group(3).strip()) for m in re.finditer(
        r"^\| ([0-9.]+) \| ([^|]+) \| ([^|]+) \|$", sec, re.M)}  # fmt: skip
    assert sorted(rows) == [3.0 + 0.5 * i for i in range(19)]
    for row in kc_map(fmu_dir, [3.0, 6.5, 7.0]):
        assert rows[row["K_c"]] == (row["observer"]["text"], row["state"]["text"]), row["K_c"]
    for fb, col, key in (("observer", 0, "sampled_with_observer"), ("full-state", 1, "sampled")):
        k_min = min(k for k in rows if all(rows[j][col].startswith("settled")
                                           for j in rows if j >= k))  # fmt: skip
        label = "with the observer" if fb == "observer" else "full-state feedback"
        assert f"| {label} | {k_min:.1f} | {an['stable_K_c'][key][0]:.2f} |" in sec
    assert rows[3.0][0].startswith("stops at 21.44 s (V_hat stalls)")
    assert "the sampled loop is stable but barely damped" in sec
    assert "the observer's transient" in sec


def test_disagreement_comments_carry_the_reason_with_numbers(report):
    text, an, _ = report
    sec = _section(text, FIGURES[3].title)
    lo = an["stable_K_c"]["sampled_with_observer"][0]
    for label, reason in (("passivity K_c = 3", f"K_c = 3 < {lo:.2f}: the sampled loop with "
                           "the observer is unstable"),
                          ("P K_P = 2", "P law, K_P = 2 (4 x the controller's default"),
                          ("PI K_P = 2, K_I = 1 Hz", "PI law, K_P = 2, K_I = 1")):  # fmt: skip
        end = re.search(rf"^\| {re.escape(label)} \| stopped \| stopped at ([0-9.]+) s \|", sec,
                        re.M).group(1)  # fmt: skip
        (line,) = [x for x in sec.splitlines() if x.startswith(f"{label}: ")]
        assert "**disagrees** with the paper" in line and reason in line, line
        assert f"V_hat stalls at {end} s (V_hat = " in line, line
        assert "after the takeover at 31.1 s the glide angle swings up to" in line
    assert not [x for x in sec.splitlines() if x.startswith("passivity K_c = 10 (ours): ")]


def test_figs_11_20_panels_name_feedback_and_mark_the_takeover(fmu_dir):
    from glider_cosim.figures.mpl import draw
    from glider_cosim.runner import simulate
    from glider_cosim.studies.report_plots import sec53_spec

    fig = FIGURES[3]
    results = [(run, simulate(apply_overrides(load_scenario(run.scenario), run.overrides), None,
                              fmu_dir=fmu_dir, build=False)) for run in fig.runs]  # fmt: skip
    f = draw(sec53_spec(fig, results))  # what fig11-20.png and report.html draw
    tops = [ax for ax in f.get_axes() if ax.get_title()]
    assert len(tops) == len(fig.runs)  # one panel per run
    groups = list(dict.fromkeys(run.group for run, _ in results))
    in_order = sorted(results, key=lambda rr: groups.index(rr[0].group))  # panels by law
    for ax, (run, r) in zip(tops, in_order, strict=True):
        title = ax.get_title()
        assert title.startswith(run.label) and "observer feedback:" in title
        assert ax.get_ylim() == (-70.0, 40.0) and ax.get_xlim() == (20.0, 90.0)
        take = [ln.get_xdata()[0] for ln in ax.get_lines() if ln.get_gid() == "event:takeover"]
        assert take == [pytest.approx(31.1, abs=0.05)]
        stops = [ln for ln in ax.get_lines() if ln.get_gid() == "event:stop"]
        assert len(stops) == (r.status != "ok")
        assert ("settled in" in title) == (r.metrics["outcome"] == "settled")


def test_report_html_renders_every_figure(report):
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from chromium_page import load

    _, _, out = report
    page = out / "report.html"
    text = page.read_text()
    assert not re.search(r"<script[^>]+src=", text)
    require_tool("chromium", "chromium-browser")
    found = load(page)
    assert found["errors"] == [] and found["console"] == [] and found["fetched"] == []
    # every figure of report.md, the region-of-attraction map (one panel per case) last
    assert len(found["figures"]) == len(FIGURES) + 3 and all(n >= 1 for n in found["figures"])
    assert found["figures"][-1] >= 3
    assert "<h2>Region of attraction" in text and "span class='key'" in text
    assert "fig2-closed-loop: " in text or FIGURES[0].key in text


def test_report_records_how_it_was_made_in_md_json_and_html(report, fmu_dir):
    from glider_cosim.fmus.files import package_version
    from glider_cosim.runner.provenance import scenario_sha256

    text, _, out = report
    sec = _section(text, "How this report was made")
    assert f"- command: `glider-cosim report --out {out} --fmu-dir {fmu_dir} --roa-grid 3x3 " \
           "--workers 2`" in sec  # fmt: skip
    assert "- region of attraction: 3 glide angles x 3 speeds, " in sec
    assert "- flavor: python\n" in sec and "- FMI version: 2.0\n" in sec
    assert f"- package version: `glider-cosim {package_version()}`" in sec
    names = {run.scenario for fig in FIGURES for run in fig.runs} | {"default", "sec53-literal"}
    for name in names:
        assert f"| {name} | `{scenario_sha256(load_scenario(name))}` |" in sec
    made = json.loads((out / "report.json").read_text())["made"]
    assert made["region of attraction"].startswith("3 glide angles x 3 speeds")
    page = (out / "report.html").read_text()
    assert "<details open><summary>How this report was made</summary>" in page
    assert made["command"] in page and scenario_sha256(load_scenario("default")) in page


def test_the_report_wraps_the_estimation_error_and_tells_divergence_from_stall(report):
    text, _, _ = report
    sec = _section(text, FIGURES[3].title)
    rows = [x for x in sec.splitlines() if re.fullmatch(r".*\| [0-9.]+ / [0-9.]+ \|", x)]
    assert len(rows) == len(FIGURES[3].runs)
    for row in rows:
        rms, peak = (float(v) for v in row.split("|")[-2].split(" / "))
        assert 0 <= rms <= peak <= 180.0, row
    for line in text.splitlines():
        for m in re.finditer(
            r"(V_hat|V) (stalls|diverges) at [0-9.]+ s \(\1 = ([^ ]+) m/s\)", line
        ):
            assert (m.group(2) == "stalls") == (float(m.group(3)) > -0.1), line
    sec34 = _section(text, FIGURES[1].title)
    (k6,) = [x for x in sec34.splitlines() if x.startswith("K_c = 6: ")]
    over = re.search(r"^\| K_c = 6 \| ok \| [^|]+\| [0-9.]+ \| ([0-9.]+) \|", sec34, re.M).group(1)
    assert f"the glide angle swings up to {over} deg past the equilibrium" in k6


def test_the_command_names_its_pages_and_every_link_of_report_md_resolves(fmu_dir, tmp_path):
    """``glider-cosim report`` prints report.md and report.html (issue 45, item 6); each
    link of report.md (the figures) resolves and none leaves its folder; the command is
    recorded as typed (issue 54)."""
    import subprocess
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1]))
    from md_links import broken_links, links

    out = tmp_path / "rep"
    proc = subprocess.run([sys.executable, "-m", "glider_cosim.cli", "report", "--roa-grid",
                           "none", "--out", str(out), "--no-progress"], capture_output=True,
                          text=True, timeout=600, check=False)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert f"wrote {out / 'report.md'}\n" in proc.stdout
    assert f"wrote {out / 'report.html'} " in proc.stdout
    md = out / "report.md"
    assert "README" not in md.read_text()  # its 'Metrics' section moved to the docs
    targets = links(md)
    # links that travel (issue 54): the figures beside it, the docs named by page only
    assert all(not t.startswith(("../", "/")) and t.endswith(".png") for t in targets), targets
    assert "the metrics' definitions (docs: reference/results.md, section 'Metrics')" in (
        md.read_text()
    )
    assert sum(t.endswith(".png") for t in targets) >= 6
    assert broken_links(md) == []
    # the command as typed, not the FMUs' folder as the cache resolved it
    typed = f"glider-cosim report --roa-grid none --out {out} --no-progress"
    assert json.loads((out / "report.json").read_text())["made"]["command"] == typed
    assert f"- command: `{typed}`" in md.read_text()
