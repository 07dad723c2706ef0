"""Units on every figure label (issue 45, item 9): every figure of the report (Figs. 2-8,
11-20, the step study, the region of attraction), a run and a sweep, drawn from made-up
runs; each axis label names its unit, each value in a title, legend entry or note is
followed by its unit (the rule: :mod:`figure_units`)."""

from __future__ import annotations

import csv
from types import SimpleNamespace

import numpy as np
from figure_units import axis_label_problem, dimensionless, quantity_problems
from report_fakes import THETA_E, FakeRun

from glider_cosim.figures import plots as run_plots
from glider_cosim.runner.provenance import marked_events
from glider_cosim.studies.figures import FIGURES
from glider_cosim.studies.report_plots import figure_spec, sec53_spec
from glider_cosim.studies.roa import CASES, CATEGORIES, RoaMap, roa_spec
from glider_cosim.studies.sec52 import TAILS_DEG, Sec52Run, sec52_spec
from glider_cosim.studies.steps import steps_spec

PLAIN = dimensionless()
#: every column a figure reads
COLUMNS = ("plant.theta_g", "observer.theta_g_hat", "plant.theta", "plant.theta_meas",
           "observer.theta_hat", "controller.delta_cmd", "plant.delta", "plant.V",
           "observer.V_hat", "plant.x", "plant.z")  # fmt: skip


def _events() -> list[dict]:
    """The marks of a run as the master makes them: enable, takeover at 1 m, a stall."""
    ev = SimpleNamespace(fired_at=31.0, delay=0.1, actions={"controller.law": 1,
                         "controller.K_c": 10.0, "controller.delta_open": 0.035},
                         variable="plant.z", op=">=", threshold=1.0)  # fmt: skip
    sim = SimpleNamespace(system=SimpleNamespace(parameters={"controller": {"t_enable": 5.0}},
                                                 events=[ev]))  # fmt: skip

    class Stop(Exception):
        time, instance = 38.8, "observer"

    return marked_events(sim, "stopped", Stop("observer: glider stalled: V = 0.0009 m/s"))


def _run(status: str = "ok", t_end: float = 60.0) -> FakeRun:
    t = np.linspace(0.0, t_end, 601)
    cols = {c: THETA_E + 0.05 * np.exp(-t / 10) * np.sin(t) for c in COLUMNS}
    cols["plant.V"] = cols["observer.V_hat"] = 0.2 + 0 * t
    cols["plant.x"], cols["plant.z"] = 0.2 * t, 0.1 * t
    metrics = {"events": _events(), "V_e_m_s": 0.24,
               "run": {"overrides": {"plant.V_0": 0.3, "controller.K_c": 6.0,
                                     "plant.theta_g_0": "-30 deg"},
                       "options": {"--stop-time": 60.0}}}  # fmt: skip
    r = FakeRun(cols, t=t, status=status, metrics=metrics, feedback="observer")
    r.scenario.parameters["plant"]["noise_std"] = 0.01
    return r


def _mpl_labels(fig) -> tuple[list[str], list[str]]:
    """(axis labels, every other text) of a matplotlib figure; tick labels left out."""
    from matplotlib.text import Text

    axis, skip = [], set()
    for ax in fig.get_axes():
        for a in (ax.xaxis, ax.yaxis):
            skip |= {id(t) for t in a.get_ticklabels(which="both")}
            skip.add(id(a.label))
            axis.append(a.label.get_text())
        skip.add(id(ax.xaxis.offsetText))
        skip.add(id(ax.yaxis.offsetText))
    other = [t.get_text() for t in fig.findobj(Text) if id(t) not in skip and t.get_text()]
    return axis, other


def _spec_labels(spec: dict) -> tuple[list[str], list[str]]:
    axis, other = [], [spec.get("title", ""), spec.get("suptitle", ""), spec.get("caption", "")]
    for p in spec["panels"]:
        axis += [p["xlabel"], p["ylabel"], *([p["colorbar"]] if "colorbar" in p else [])]
        other += [p["title"], *(ln["name"] for ln in p["lines"]), *(t["text"] for t in p["texts"])]
    return axis, [t for t in other if t]


def _problems(axis: list[str], other: list[str]) -> list[str]:
    out = [p for p in map(axis_label_problem, axis) if p]
    for text in other:
        out += quantity_problems(text, PLAIN)
    return out


def _report_figures(tmp_path) -> list[dict]:
    """The report's figures' specs."""
    by = {f.key: f for f in FIGURES}
    figs = [figure_spec(by[key], [(run, _run("stopped" if k else "ok"))
                                  for k, run in enumerate(by[key].runs)])
            for key in ("fig2", "fig3-4", "fig5-6")]  # fmt: skip
    figs.append(sec53_spec(by["fig11-20"], [(run, _run()) for run in by["fig11-20"].runs]))
    t = np.linspace(0.0, 60.0, 601)
    trace = THETA_E + 0.01 * np.sin(t)
    steps = steps_spec({"traces": {"t": t, "50 Hz": trace, "200 Hz": trace,
                                   "continuous": trace}})  # fmt: skip
    fig8 = sec52_spec([Sec52Run(tail, k, _run(), 2.0, None, None, None, 0.0)
                       for k in (1.0, 0.039) for tail in TAILS_DEG])  # fmt: skip
    cells = np.array([[CATEGORIES[(i + j) % len(CATEGORIES)] for j in range(3)]
                      for i in range(3)], dtype=object)  # fmt: skip
    maps = [RoaMap(c, np.radians([-30.0, 0.0, 30.0]), np.array([0.1, 0.2, 0.3]), cells, 60.0,
                   1.0) for c in CASES]  # fmt: skip
    return [*figs, steps, fig8, roa_spec(maps)]


def test_the_rule_flags_a_value_without_its_unit():
    assert quantity_problems("observer under noise R = 0.1 (full-state)", PLAIN)
    assert quantity_problems("PI K_P = 2, K_I = 1", PLAIN) == [
        "'PI K_P = 2, K_I = 1': K_I = 1 has no unit"]  # fmt: skip
    assert quantity_problems("takeover at plant.z >= 1 (controller.law = passivity)", PLAIN)
    assert not quantity_problems("K_c = 2, 3, 6; R = 0.1 rad^2; t = 5.00 s", PLAIN)
    assert axis_label_problem("K_c") and not axis_label_problem("K_c [1]")


def test_every_report_figure_labels_its_quantities_with_units(tmp_path):
    from glider_cosim.figures.mpl import draw

    specs = _report_figures(tmp_path)
    assert len(specs) == 7
    problems = [p for s in specs for p in _problems(*_spec_labels(s))]
    problems += [p for s in specs for p in _problems(*_mpl_labels(draw(s)))]  # as drawn
    assert problems == []


def test_every_run_figure_labels_its_quantities_with_units(tmp_path):
    specs = [spec for spec, _, _ in run_plots.build_specs(_run("stopped"), tmp_path)]
    assert len(specs) == 5
    problems = [p for s in specs for p in _problems(*_spec_labels(s))]
    assert problems == []


def test_every_sweep_figure_labels_its_quantities_with_units(tmp_path):
    from glider_cosim.sweeps.plots import sweep_specs, write_plots

    path = tmp_path / "sweep.csv"
    fields = ["controller.K_c", "plant.noise_std", "status", "settling_time_s",
              "control_effort", "estimation_rms_rad"]  # fmt: skip
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fields)
        w.writeheader()
        for k, (kc, std) in enumerate([(2, 0.01), (4, 0.02), (6, 0.03), (8, 0.04)]):
            w.writerow({"controller.K_c": kc, "plant.noise_std": std,
                        "status": "ok" if k else "stopped",
                        "settling_time_s": 20 - kc if k > 1 else "", "control_effort": 0.1 * kc,
                        "estimation_rms_rad": 0.01 * k})  # fmt: skip
    assert len(write_plots(path, tmp_path)) == 3
    with open(path, newline="") as f:
        specs = [spec for _, spec in sweep_specs(list(csv.DictReader(f)))]
    assert len(specs) == 3 and "controller.K_c [1]" in _spec_labels(specs[0])[0]
    problems = [p for s in specs for p in _problems(*_spec_labels(s))]
    assert problems == []
