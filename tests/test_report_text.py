"""The report says true things (issue 28 point 5): the estimation error wrapped to
[-180, 180) deg, "stalls" only for a speed that fell to zero, the overshoot quoted as
the swing past the target, and a section on how the report was made."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from glider_cosim.runner.outcome import wrap_angle
from glider_cosim.studies.figures import DEG, estimation_error, how_it_ends, stop_reason
from glider_cosim.studies.report_text import _swing, provenance_markdown


class FakeRun:
    """What the report reads off a RunResult: columns, data, message, status, metrics."""

    def __init__(self, columns, data, message="", status="ok", metrics=None):
        self.columns, self.data = list(columns), np.asarray(data, dtype=float)
        self.message, self.status, self.metrics = message, status, metrics or {}

    def column(self, name):
        return self.data[:, self.columns.index(name)]


def test_wrap_angle_is_in_minus_pi_inclusive_to_pi_exclusive():
    x = np.array([math.pi, -math.pi, 3 * math.pi, 2 * math.pi, 1.5 * math.pi, -0.25, 7.0])
    w = wrap_angle(x)
    assert w.tolist() == pytest.approx([-math.pi, -math.pi, -math.pi, 0.0, -0.5 * math.pi,
                                        -0.25, 7.0 - 2 * math.pi])  # fmt: skip
    assert np.all(w >= -math.pi) and np.all(w < math.pi)
    assert float(wrap_angle(math.pi)) == float(wrap_angle(-math.pi)) == -math.pi
    assert float(wrap_angle(180.0, 360.0)) == -180.0 and float(wrap_angle(-190.0, 360.0)) == 170.0


def test_one_wrap_gives_the_metrics_and_the_outcome_their_bits():
    """The metrics' error (compute_metrics) and the outcome's (classify) were wrapped
    inline as ``mod(e + pi, 2 pi) - pi``, the Sec. 5.2 plots' degrees as
    ``(a + 180) % 360 - 180``: the one wrap gives the same bits, and small estimation
    errors the same bits as the former (-pi, pi] wrap ``pi - mod(pi - e, 2 pi)``."""
    e = np.random.default_rng(1).uniform(-20.0, 20.0, 10_000)
    assert np.array_equal(wrap_angle(e), np.mod(e + math.pi, 2.0 * math.pi) - math.pi)
    deg = e * DEG
    assert np.array_equal(wrap_angle(deg, 360.0), (deg + 180.0) % 360.0 - 180.0)
    small = e / 400.0  # within 0.05 rad, like an estimation error after the transient
    assert np.array_equal(wrap_angle(small), math.pi - np.mod(math.pi - small, 2 * math.pi))


def test_estimation_error_of_an_estimate_a_turn_away_is_small():
    t = np.linspace(0.0, 10.0, 101)
    truth = -0.4 + 0.01 * np.sin(t)
    # the estimate is off by 0.02 rad, then jumps one turn (and more) away halfway
    est = truth + 0.02 + np.where(t > 5.0, 2 * math.pi, 0.0) + np.where(t > 8.0, 2 * math.pi, 0)
    r = FakeRun(["time", "plant.theta_g", "observer.theta_g_hat"], np.c_[t, truth, est])
    rms, peak, w0, w1 = estimation_error(r)
    assert rms * DEG == pytest.approx(0.02 * DEG) and peak * DEG == pytest.approx(0.02 * DEG)
    assert (w0, w1) == (5.0, 10.0)


def _stopped(instance: str, v: str, t_end: float = 38.8) -> FakeRun:
    what = "observer estimate glider stalled" if instance == "observer" else "glider stalled"
    msg = (f"{instance}: fmi2DoStep at t = {t_end} s returned fmi2Discard: [fmi2Discard] "
           f"{instance}: {what}: V = {v} m/s (model valid for V > 0.001 m/s, Eq. (7) divides "
           "by V)")  # fmt: skip
    return FakeRun(["time"], [[0.0], [t_end]], msg, "stopped")


@pytest.mark.parametrize(
    ("instance", "v", "reason"),
    [("observer", "-249.7", "V_hat diverges at 38.80 s (V_hat = -2.5e+02 m/s)"),
     ("observer", "-0.0035", "V_hat stalls at 38.80 s (V_hat = -0.0035 m/s)"),
     ("observer", "0.000998", "V_hat stalls at 38.80 s (V_hat = 0.001 m/s)"),
     ("plant", "nan", "V diverges at 38.80 s (V = nan m/s)"),
     ("plant", "-inf", "V diverges at 38.80 s (V = -inf m/s)"),
     ("plant", "-0.5", "V diverges at 38.80 s (V = -0.5 m/s)")],
)  # fmt: skip
def test_only_a_speed_that_fell_to_zero_stalls(instance, v, reason):
    r = _stopped(instance, v)
    assert stop_reason(r) == reason
    name, verb = reason.split()[:2]
    assert how_it_ends(r) == f"stops at 38.80 s ({name} {verb})"


def test_a_run_stopped_for_another_reason_has_no_stall():
    assert stop_reason(FakeRun(["time"], [[0.0], [1.0]], "plant: fmi2Error", "error")) is None


def test_the_swing_quoted_is_the_overshoot_past_the_target():
    err = np.array([12.5, 3.0, -8.05, 2.0]) / DEG  # from 12.5 deg off to 8.05 deg past
    assert _swing(err, 8.05 / DEG) == "swings up to 8.05 deg past the equilibrium"
    assert _swing(err[:2], 0.0) == (
        "does not pass the equilibrium (largest distance from it 12.50 deg)"
    )


def test_provenance_section_lists_options_and_every_scenario_hash():
    made = {"command": "glider-cosim report --out out/report --roa-grid none --workers 2",
            "region of attraction": "skipped (--roa-grid none)", "flavor": "python",
            "FMI version": "2.0", "package version": "glider-cosim 0.1.0", "Python": "3.11.7",
            "scenarios": {"default": "ab" * 32, "sec53-protocol": "cd" * 32}}  # fmt: skip
    assert provenance_markdown(made) == [
        "## How this report was made",
        "",
        "- command: `glider-cosim report --out out/report --roa-grid none --workers 2`",
        "- region of attraction: skipped (--roa-grid none)",
        "- flavor: python",
        "- FMI version: 2.0",
        "- package version: `glider-cosim 0.1.0`",
        "- Python: 3.11.7",
        "",
        "| scenario | SHA-256 |",
        "|---|---|",
        f"| default | `{'ab' * 32}` |",
        f"| sec53-protocol | `{'cd' * 32}` |",
        "",
    ]


@pytest.mark.parametrize(("v", "what"), [("-249.7", "diverged"), ("0.000998", "stalled")])
def test_a_run_plot_marks_a_diverged_estimate_as_diverged(v, what):
    from types import SimpleNamespace

    from glider_cosim.runner.provenance import marked_events

    sim = SimpleNamespace(system=SimpleNamespace(parameters={}, events=[]))
    msg = _stopped("observer", v).message

    class Stop(Exception):
        time, instance = 38.8, "observer"

        def __str__(self):
            return msg

    (ev,) = marked_events(sim, "stopped", Stop())
    assert ev == {"kind": "stall", "time_s": 38.8, "label": f"observer {what} (fmi2Discard)"}


def test_the_link_checker_finds_a_missing_file_and_a_missing_anchor(tmp_path):
    from md_links import broken_links

    readme = Path(__file__).resolve().parents[1] / "README.md"
    md = tmp_path / "x.md"
    md.write_text(f"# Top\n\n[ok]({readme}#quick-start) [self](#top) ![png](fig.png) "
                  f"[gone]({readme}#metrics) [none](nothing.md) `[code](skip.md)`\n")  # fmt: skip
    (tmp_path / "fig.png").write_bytes(b"")
    bad = broken_links(md)
    assert len(bad) == 2 and "#metrics" in bad[0] and "nothing.md" in bad[1]


@pytest.mark.parametrize("depth", ["report", "a/b/c/report"])
def test_the_report_names_the_metrics_definitions_without_a_path(tmp_path, depth):
    """report.md travels (copied, read on another machine): the docs are named by page
    and section, never linked by a path into the clone or the cache (issue 54)."""
    from md_links import broken_links, links

    from glider_cosim.studies.kc_map import kc_map_markdown
    from glider_cosim.studies.report_text import docs_reference

    out = tmp_path / depth
    out.mkdir(parents=True)
    ref = docs_reference("reference/results.md", "Metrics", "the metrics' definitions")
    assert ref == "the metrics' definitions (docs: reference/results.md, section 'Metrics')"
    cell = {"text": "settled in 9.00 s", "outcome": "settled"}
    rows = [{"K_c": k, "observer": cell, "state": cell}
            for k in (3.0, 3.5)]  # fmt: skip
    md = out / "report.md"
    md.write_text("\n".join(kc_map_markdown(rows, None, ref)) + "\n")
    assert links(md) == [] and broken_links(md) == []
    assert "../" not in md.read_text() and str(tmp_path) not in md.read_text()
    assert ref in md.read_text()
