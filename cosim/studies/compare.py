"""``glider-cosim compare``: the user's controller (or estimator) against ours, on the
paper's benchmark set.

Every case runs twice on the same master with our plant: once with our component, once
with theirs (the scenario's ``[fmus]``; the other component stays ours), so that the
only difference between the two columns is their component. The cases
(:func:`benchmark`): the default start (Sec. 3.3), the noisy pitch (Figs. 5-6, fed back
through the estimator so that the noise reaches the law), the depth protocol (Sec. 5.3:
both from the state where the protocol hands over to the law at 1 m depth, found by our
run of ``sec53-protocol``), and a grid of starts (glide angles :data:`GRID_DEG`).
Written: ``compare.csv``, ``compare.md``, ``compare.html`` and one overlay PNG per case.
"""

from __future__ import annotations

import csv
import dataclasses
import html
import logging
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..fmus.variables import LAW_NAMES
from ..inputs.outputs import check_out_dir
from ..progress import Progress, home
from ..runner.run import RunResult, simulate
from ..scenarios.scenario import Scenario, load_scenario


class CompareError(ValueError):
    """Bad input to ``compare`` (the scenario swaps no controller or estimator, ...)."""


#: the components ``compare`` compares, and what the page calls them
COMPARED = {"controller": "controller", "observer": "estimator"}
#: the grid's starting glide angles (deg)
GRID_DEG = (-45.0, -30.0, -15.0, -5.0)
#: the depth at which the Sec. 5.3 protocol hands over to the law (m)
HANDOVER_DEPTH = 1.0
_LAW = {name: code for code, name in LAW_NAMES.items()}
#: the plant's state at a point -> its start parameters
_STATE = {"V": "V_0", "theta_g": "theta_g_0", "alpha": "alpha_0", "omega2": "omega2_0",
          "delta": "delta_0", "x": "x_0", "z": "z_0"}  # fmt: skip


@dataclass(frozen=True)
class Measure:
    """One column of the table: a name, its unit, how it is read from a run."""

    name: str
    unit: str
    read: Callable[[RunResult], float | None]


def _deg(key: str) -> Callable[[RunResult], float | None]:
    return lambda r: None if r.metrics.get(key) is None else math.degrees(r.metrics[key])


def _tail(r: RunResult) -> float | None:
    col = "plant.delta" if "plant.delta" in r.columns else "controller.delta_cmd"
    return float(np.max(np.abs(np.degrees(r.column(col))))) if len(r.data) else None


#: the measures, each smaller is better (a run that never settles has no settling time)
MEASURES = (
    Measure("settling", "s", lambda r: r.metrics.get("settling_time_s")),
    Measure("rise", "s", lambda r: r.metrics.get("rise_time_s")),
    Measure("overshoot", "deg", _deg("overshoot_rad")),
    Measure("effort", "rad s", lambda r: r.metrics.get("control_effort")),
    Measure("largest tail angle", "deg", _tail),
)


@dataclass
class Case:
    """One benchmark case: its name, what it is, and its two runs."""

    name: str
    title: str
    ours: RunResult
    theirs: RunResult

    def verdicts(self) -> dict[str, str]:
        """Measure (and ``outcome``) -> ``better``, ``worse`` or ``same``, for theirs."""
        out = {}
        for m in MEASURES:
            a, b = m.read(self.ours), m.read(self.theirs)
            if a is None and b is None:
                out[m.name] = "same"
            elif a is None or b is None:
                out[m.name] = "better" if a is None else "worse"
            else:
                out[m.name] = _cmp(b, a)
        settled = [r.metrics.get("outcome") == "settled" for r in (self.ours, self.theirs)]
        out["outcome"] = ("same" if settled[0] == settled[1]
                          else "better" if settled[1] else "worse")  # fmt: skip
        return out


def _cmp(theirs: float, ours: float) -> str:
    if abs(theirs - ours) <= 1e-3 * max(abs(ours), 1e-9) + 1e-12:
        return "same"
    return "better" if theirs < ours else "worse"


def swapped_component(user: Scenario) -> str:
    """The component ``user`` puts in the loop (its ``[fmus]``): controller or observer.

    Raises
    ------
    CompareError
        It swaps neither, both, or the plant.
    """
    mine = set(user.fmus)
    if mine - set(COMPARED) or len(mine) != 1:
        got = ", ".join(sorted(mine)) or "nothing"
        raise CompareError(
            f"{user.source}: [fmus] swaps {got}: expected exactly one of controller or "
            "observer (compare puts your component in our loop, beside ours)"
        )
    return next(iter(mine))


def _theirs(base: Scenario, user: Scenario, component: str) -> Scenario:
    """``base`` with the user's component (and its parameters from ``user``) in place of
    ours; events and disturbances on it dropped (they set our law's parameters)."""
    params = {k: v for k, v in base.parameters.items() if k != component}
    if user.parameters.get(component):
        params[component] = dict(user.parameters[component])
    return dataclasses.replace(
        base, name=f"{base.name}-theirs", parameters=params, fmus=dict(user.fmus),
        events=[e for e in base.events
                if not any(t.startswith(f"{component}.") for t in e.actions)],
        origins={},
    )  # fmt: skip


def _start(base: Scenario, name: str, **plant: Any) -> Scenario:
    params = {k: dict(v) for k, v in base.parameters.items()}
    params.setdefault("plant", {}).update(plant)
    return dataclasses.replace(base, name=name, parameters=params, origins={})


def benchmark(ours_protocol: RunResult | None = None) -> list[tuple[str, str, Scenario]]:
    """The cases as (name, title, our scenario); the depth protocol's needs our run of
    ``sec53-protocol`` (``ours_protocol``) for the state where it hands over."""
    default = load_scenario("default")
    noisy = dataclasses.replace(load_scenario("fig5-6-observer-noise"), feedback="observer")
    cases = [
        ("default", "the default start (Sec. 3.3, -35 deg)", default),
        ("noisy-pitch", "the noisy pitch (Figs. 5-6, R = 0.1 rad^2)", noisy),
    ]
    if ours_protocol is not None:
        proto = load_scenario("sec53-protocol")
        z = ours_protocol.column("plant.z")
        k = int(np.argmax(z >= HANDOVER_DEPTH))
        if z[k] >= HANDOVER_DEPTH:
            state = {p: float(ours_protocol.column(f"plant.{v}")[k]) for v, p in _STATE.items()}
            t_h = float(ours_protocol.column("time")[k])
            stop = round((proto.stop_time - t_h) / proto.step) * proto.step
            hand = _start(proto, "sec53-handover", **state)
            ctrl = {**hand.parameters.get("controller", {}), "law": _LAW["passivity"]}
            hand = dataclasses.replace(
                hand, stop_time=stop, events=[],
                parameters={**hand.parameters, "controller": ctrl},
            )  # fmt: skip
            cases.append(("depth-protocol", f"the depth protocol (Sec. 5.3), from the "
                          f"hand-over at {HANDOVER_DEPTH:g} m, t = {t_h:.2f} s", hand))  # fmt: skip
    for deg in GRID_DEG:
        name = f"start{deg:+.0f}deg"
        cases.append((name, f"a start at {deg:g} deg",
                       _start(default, name, theta_g_0=math.radians(deg))))  # fmt: skip
    return cases


@contextmanager
def _restored(logger: logging.Logger, level: int) -> Iterator[None]:
    try:
        yield
    finally:
        logger.setLevel(level)


def default_out(scenario: str | Path) -> Path:
    """``out/<scenario name>-compare``, the folder of ``compare`` unless one is given."""
    return Path("out") / f"{load_scenario(scenario).name}-compare"


def compare(
    scenario: str | Path, out: str | Path | None = None, fmu_dir: str | Path | None = None
) -> dict[str, Any]:
    """Run the benchmark set with the user's component and with ours; write the table,
    the overlay figures and the pages.

    Parameters
    ----------
    scenario : path or shipped name
        A scenario whose ``[fmus]`` swaps the controller or the observer (read only,
        and their FMU too).
    out : path, optional
        Folder for the files (default ``out/<scenario name>-compare``), checked before
        any run.
    fmu_dir : path, optional
        Our FMUs (built there if missing or stale; default: the per-user cache).

    Returns
    -------
    dict
        ``cases`` (list of :class:`Case`), ``files`` (name -> Path), ``component``.

    Raises
    ------
    CompareError, ScenarioError, UsageError
        Bad input (one line); raised before any run.
    """
    user = load_scenario(scenario)
    component = swapped_component(user)
    out = Path(out) if out is not None else default_out(scenario)
    check_out_dir(out, "--out")
    fmu = Path(user.fmus[component]).resolve()
    n_grid = len(GRID_DEG)
    cases: list[Case] = []
    notes = logging.getLogger("glider_cosim.runner.run")
    level = notes.level
    header = f"comparing {fmu.name} with our {component} on {3 + n_grid} cases"
    with Progress(2 * (3 + n_grid) + 1, "compare", header) as bar, _restored(notes, level):
        bar.step("our depth protocol (sec53-protocol)")
        proto = simulate("sec53-protocol", None, fmu_dir=fmu_dir, plots=False)
        for name, title, ours in benchmark(proto):
            bar.step(f"{name}: ours")
            r_ours = simulate(ours, None, fmu_dir=fmu_dir, plots=False)
            bar.step(f"{name}: theirs")
            r_theirs = simulate(_theirs(ours, user, component), None, fmu_dir=fmu_dir,
                                plots=False)  # fmt: skip
            cases.append(Case(name, title, r_ours, r_theirs))
            notes.setLevel(logging.ERROR)  # the wiring's notes: once, for the first case
    out.mkdir(parents=True, exist_ok=True)
    files = {"csv": out / "compare.csv"}
    _write_csv(files["csv"], cases)
    pngs = {c.name: _overlay(c, fmu.stem, out / f"compare-{c.name}.png") for c in cases}
    files.update({f"png:{k}": v for k, v in pngs.items()})
    text = compare_markdown(cases, fmu.name, component, pngs)
    files["md"] = out / "compare.md"
    files["md"].write_text(text)
    files["html"] = out / "compare.html"
    files["html"].write_text(compare_html(cases, fmu.name, component, pngs))
    return {"cases": cases, "files": files, "component": component}


def _value(v: float | None, unit: str) -> str:
    return "n/a" if v is None else f"{v:.3g} {unit}"


def _rows(cases: list[Case]) -> list[list[str]]:
    head = ["case"] + [f"{m.name} ours / theirs" for m in MEASURES] + ["outcome ours / theirs"]
    rows = [head]
    for c in cases:
        v = c.verdicts()
        row = [c.name]
        for m in MEASURES:
            row.append(f"{_value(m.read(c.ours), m.unit)} / "
                       f"{_value(m.read(c.theirs), m.unit)} ({v[m.name]})")  # fmt: skip
        row.append(f"{c.ours.metrics.get('outcome')} / {c.theirs.metrics.get('outcome')} "
                   f"({v['outcome']})")  # fmt: skip
        rows.append(row)
    return rows


def _write_csv(path: Path, cases: list[Case]) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["case", "measure", "unit", "ours", "theirs", "theirs_is"])
        for c in cases:
            v = c.verdicts()
            for m in MEASURES:
                w.writerow([c.name, m.name, m.unit, m.read(c.ours), m.read(c.theirs), v[m.name]])
            w.writerow([c.name, "outcome", "", c.ours.metrics.get("outcome"),
                        c.theirs.metrics.get("outcome"), v["outcome"]])  # fmt: skip


def summary_lines(cases: list[Case]) -> list[str]:
    """Plain sentences: per case, where theirs beats ours and where not."""
    lines = []
    for c in cases:
        v = c.verdicts()
        better = [k for k, x in v.items() if x == "better"]
        worse = [k for k, x in v.items() if x == "worse"]
        lines.append(
            f"{c.name} ({c.title}): theirs is better in "
            f"{', '.join(better) or 'nothing'}; worse in {', '.join(worse) or 'nothing'}"
        )
    return lines


def compare_markdown(cases: list[Case], fmu: str, component: str, pngs: dict[str, Path]) -> str:
    """``compare.md``: what was compared, the verdicts in words, the table, the figures."""
    who = COMPARED[component]
    other = "our controller" if component == "observer" else "our estimator"
    lines = [f"# {fmu} against our {who}", "",
             f"Each case ran twice on the same master and our plant ({other} around it): "
             f"once with our {who}, once with {fmu}. Smaller is better for every measure; "
             "a run that does not settle has no settling time (worse than any).", "",
             "## Where theirs beats ours, and where not", ""]  # fmt: skip
    lines += [f"- {s}" for s in summary_lines(cases)] + ["", "## The table", ""]
    rows = _rows(cases)
    lines.append("| " + " | ".join(rows[0]) + " |")
    lines.append("|" + "---|" * len(rows[0]))
    lines += ["| " + " | ".join(r) + " |" for r in rows[1:]]
    lines += ["", "## The figures", ""]
    for c in cases:
        lines += [f"### {c.name}: {c.title}", "", f"![{c.name}]({pngs[c.name].name})", ""]
    return "\n".join(lines)


def compare_html(cases: list[Case], fmu: str, component: str, pngs: dict[str, Path]) -> str:
    """``compare.html``: the same as ``compare.md``, one page with its figures beside it."""
    e = html.escape
    who = COMPARED[component]
    rows = _rows(cases)
    body = [f"<h1>{e(fmu)} against our {who}</h1>",
            "<p>Same master, our plant; the only difference between the columns is the "
            f"{who}. Smaller is better for every measure.</p>",
            "<h2>Where theirs beats ours, and where not</h2><ul>"]  # fmt: skip
    body += [f"<li>{e(s)}</li>" for s in summary_lines(cases)] + ["</ul>", "<table>"]
    body.append("<tr>" + "".join(f"<th>{e(h)}</th>" for h in rows[0]) + "</tr>")
    for r in rows[1:]:
        cells = []
        for cell in r:
            cls = "better" if "(better)" in cell else "worse" if "(worse)" in cell else ""
            cells.append(f'<td class="{cls}">{e(cell)}</td>')
        body.append("<tr>" + "".join(cells) + "</tr>")
    body.append("</table>")
    for c in cases:
        img = f'<img src="{e(pngs[c.name].name)}" alt="{e(c.name)}" width="800">'
        body.append(f"<h3>{e(c.name)}: {e(c.title)}</h3>{img}")
    style = ("body{font-family:sans-serif;max-width:70em;margin:auto}"
             "td,th{border:1px solid #ccc;padding:3px}table{border-collapse:collapse}"
             ".better{background:#d8f5d8}.worse{background:#f8dada}")  # fmt: skip
    return (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{e(fmu)} against "
            f"our {who}</title><style>{style}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")  # fmt: skip


def _overlay(case: Case, theirs_name: str, path: Path) -> Path:
    """One case's overlay: glide angle and tail angle over time, ours and theirs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    for r, label, style in ((case.ours, "ours", "-"), (case.theirs, theirs_name, "--")):
        t = r.column("time")
        ax1.plot(t, np.degrees(r.column("plant.theta_g")), style, label=label)
        tail = "plant.delta" if "plant.delta" in r.columns else "controller.delta_cmd"
        ax2.plot(t, np.degrees(r.column(tail)), style, label=label)
    theta_ge = case.ours.metrics.get("theta_ge_rad")
    if theta_ge is not None:
        ax1.axhline(math.degrees(theta_ge), color="0.6", lw=0.8, label="steady glide")
    ax1.set_ylabel("glide angle (deg)")
    ax2.set_ylabel("tail angle (deg)")
    ax2.set_xlabel("time (s)")
    ax1.set_title(f"{case.name}: {case.title}", fontsize=10)
    ax1.legend(fontsize=8)
    ax1.grid(alpha=0.3)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def describe(result: dict[str, Any]) -> str:
    """The console's summary: one line per case, then the files."""
    lines = summary_lines(result["cases"])
    files = result["files"]
    lines.append(f"wrote {home(files['md'])}, {home(files['html'])}, {home(files['csv'])} "
                 f"and {sum(k.startswith('png:') for k in files)} figures")  # fmt: skip
    return "\n".join(lines)
