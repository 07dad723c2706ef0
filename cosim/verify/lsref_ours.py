"""Our FMUs' FMI-LS-REF folders (``python -m glider_cosim.verify.lsref_ours --write |
--check [--component NAME]``), shipped in each component's folder
(``src/<component>/lsref/``) and packed by every build (:mod:`glider_cosim.fmus.lsref`),
and recording an instance of a loop at component level (:func:`record_component`, also
for ``glider-cosim add-experiments``). :mod:`glider_cosim.interop.lsref_write` says what
the folders hold."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..components import component as registry_component
from ..fmus.lsref import LSREF_DIR, MANIFEST, shipped_folder
from ..interop.lsref_write import (
    SMOKE_TOLERANCE,
    SSV_MIME,
    VALIDATION_TOLERANCE,
    Experiment,
    LsrefError,
    Related,
    experiment_files,
    manifest_bytes,
    ssv_bytes,
)
from .reference import CASES, STEP, STOP, cases_asked

# ------------------------------------------------------------------ our FMUs
#: model name -> component, of every registered component with a reference case (its
#: folder's reference_input.csv): the smoke test; those of the default loop also get the
#: validation and the shipped scenarios' parameter sets
OURS = {model: case["component"] for model, case in CASES.items()}
#: the scenario the validation experiment is recorded from
VALIDATION_SCENARIO = "default"


def _package_dir(name: str) -> Path:
    return registry_component(name).folder


def _differs(value: Any, start: Any) -> bool:
    if start is None:
        return True
    if isinstance(value, bool) or isinstance(start, bool):
        return str(value).lower() != str(start).lower()
    try:
        return float(value) != float(start)
    except (TypeError, ValueError):
        return True


def scenario_sets(component: str, starts: Mapping[str, Any]) -> list[tuple[str, str, dict]]:
    """(scenario name, summary, values) of each shipped scenario whose values of the
    component's parameters differ from the FMU's start values (only those values)."""
    from ..scenarios.sampling import with_sampling
    from ..scenarios.scenario import load_scenario, one_line_summary, shipped_scenarios

    out = []
    for name in shipped_scenarios():
        sc = load_scenario(name)
        if component == "observer" and not sc.observer:
            continue
        params = with_sampling(sc.parameters, sc.step, sc.source, sc.observer)
        values = {k: v for k, v in params.get(component, {}).items()
                  if _differs(v, starts.get(k))}  # fmt: skip
        if values:
            out.append((name, one_line_summary(sc, 200), values))
    return out


def smoke_experiment(model: str) -> Experiment:
    """The component's reference case (``src/<component>/reference_*.csv``)."""
    from .cases import read_table

    pkg = _package_dir(OURS[model])
    return Experiment(
        "reference",
        f"{model} alone on its reference inputs (glider-cosim's reference case)",
        0.0,
        STOP,
        STEP,
        SMOKE_TOLERANCE,
        read_table(pkg / "reference_output.csv"),
        read_table(pkg / "reference_input.csv"),
        dict(CASES[model]["parameters"]),
    )


def model_related(model: str, fmu_dir: Path) -> list[Related]:
    """Every file of one of our models' LS-REF folder but the manifest: the smoke test,
    the validation (recorded from the default loop with the FMUs of ``fmu_dir``), the
    scenarios' parameter sets, the readme."""
    from fmpy import read_model_description

    from ..scenarios.scenario import load_scenario

    component = OURS[model]
    md = read_model_description(str(fmu_dir / f"{model}.fmu"))
    types = {v.name: v.type for v in md.modelVariables}
    starts = {v.name: v.start for v in md.modelVariables}
    related = experiment_files(
        "smoke-test",
        [smoke_experiment(model)],
        types,
        "experiment/smoke-test",
        f"{model} smoke test",
        f"{model}: the reference case of glider-cosim's {component}",
    )
    if not registry_component(component).in_every_run:  # added by a scenario: no
        return [*related, _readme(model)]  # validation in the default loop
    sc = load_scenario(VALIDATION_SCENARIO)
    ex = record_component(sc, component, fmu_dir)
    ex.description = (
        f"{model} in the loop of the paper's default scenario (Sec. 3.3, {ex.stop:g} s): its "
        "inputs recorded from a run of the loop, its outputs as references"
    )
    related += experiment_files(
        "validation",
        [ex],
        types,
        "experiment/validation",
        f"{model} validation",
        f"{model}: the paper's default start, component level",
    )
    for name, summary, values in scenario_sets(component, starts):
        related.append(
            Related(
                f"parameters/{name}.ssv",
                "parameter",
                SSV_MIME,
                f"scenario {name}: {summary}",
                ssv_bytes(name, values, types),
                (("scenario", name),),
            )
        )
    related.append(_readme(model))
    return related


def _readme(model: str) -> Related:
    """The component's readme, as the LS-REF folder's document."""
    return Related(
        "README.md",
        "document",
        "text/markdown",
        f"{model}: the component's readme (model, equations, variables)",
        (_package_dir(OURS[model]) / "README.md").read_bytes(),
    )


def folder_files(related: Sequence[Related]) -> dict[str, bytes]:
    """Path in the LS-REF folder -> bytes: every file of ``related`` and the manifest."""
    out = {r.source: r.data for r in related}
    out[MANIFEST.removeprefix(LSREF_DIR + "/")] = manifest_bytes(related)
    return out


def write_folders(
    fmu_dir: str | Path | None = None,
    dest: Path | None = None,
    models: Sequence[str] | None = None,
) -> list[Path]:
    """Write our models' LS-REF folders (``models``, default every one of :data:`OURS`),
    each replaced whole: into ``dest/<model>/``, or by default each component's
    ``lsref/`` (:func:`~glider_cosim.fmus.lsref.shipped_folder`). The FMUs of ``fmu_dir``
    (default: the per-user cache's Python flavor, built if missing or stale) run the loop.
    Return the files written."""
    import shutil

    from ..fmus.folders import build_all, fmu_folder

    folder = fmu_folder(fmu_dir)
    build_all(folder, only_stale=True)
    written = []
    for model in OURS if models is None else models:
        files = folder_files(model_related(model, folder))
        out = shipped_folder(model) if dest is None else Path(dest) / model
        if out.exists():
            shutil.rmtree(out)
        for rel, data in files.items():
            path = out / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
            written.append(path)
    return written


# ------------------------------------------------------------------ recording a loop
def record_component(scenario: Any, instance: str, fmu_dir: Path) -> Experiment:
    """Run ``scenario``'s loop with our master and record one instance at component level:
    its inputs (connected or driven) as stimuli, its outputs as references, the values the
    scenario gives its parameters.

    A row holds an input as it was when the row was read; with Gauss-Seidel coupling an
    instance stepped after the one feeding it has used the next row's value over a step.
    The stimuli are the values each step used: of the two alignments (this row's or the
    next row's values), the one with which the instance alone, run by the verifier
    (fmpy), reproduces its outputs in the loop at :data:`VALIDATION_TOLERANCE`.

    Raises
    ------
    LsrefError
        The instance alone reproduces its outputs with neither alignment (one line with
        its worst variable).
    """
    from fmpy import read_model_description

    from ..master.cosimulation import CoSimulation
    from ..runner.recorders import ArrayRecorder
    from ..scenarios.system import system_for

    system = system_for(scenario, Path(fmu_dir), scenario.step)
    md = read_model_description(str(system.fmus[instance]))
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    system.record = [f"{instance}.{n}" for n in (*inputs, *outputs)]
    sim = CoSimulation(system, step=scenario.step, coupling=scenario.coupling)
    rec = ArrayRecorder()
    try:
        sim.run(scenario.stop_time, rec)
    finally:
        sim.close()
    cols = [c.removeprefix(f"{instance}.") for c in rec.columns]
    data = rec.array(len(cols))
    idx = {c: i for i, c in enumerate(cols)}
    stim = data[:, [0] + [idx[n] for n in inputs]]
    ref = data[:, [0] + [idx[n] for n in outputs]]
    params = dict(system.parameters.get(instance, {}))
    worst = ""
    for shift in (0, 1):
        held = stim.copy()
        if shift:
            held[:-1, 1:] = stim[1:, 1:]
        ex = Experiment(
            scenario.name,
            f"{instance} in the loop of scenario {scenario.name!r}",
            0.0,
            scenario.stop_time,
            scenario.step,
            VALIDATION_TOLERANCE,
            (["time", *outputs], ref),
            (["time", *inputs], held),
            params,
        )
        worst = replay_differs(Path(system.fmus[instance]), md, ex)
        if not worst:
            return ex
    raise LsrefError(
        f"{instance} ({Path(system.fmus[instance]).name}) alone on the inputs recorded from "
        f"the loop does not reproduce its outputs there: {worst}"
    )


def value_text(v: Any) -> str:
    """A parameter value as text (``true``/``false``, an integer, a float's ``repr``)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    return repr(float(v))


def replay_differs(fmu: Path, md: Any, ex: Experiment) -> str:
    """Run ``ex`` on ``fmu`` with the verifier's runner (fmpy); empty if it passes, else
    its worst variable in words."""
    import tempfile

    import fmpy

    from .lsref_report import Planned, compare
    from .lsref_run import simulate

    kinds = {v.name: v.type for v in md.modelVariables}
    planned = Planned(
        "<recorded>",
        "experiment",
        ex.name,
        ex.tolerance,
        ex.start,
        ex.stop,
        ex.step,
        {k: (kinds[k], value_text(v)) for k, v in ex.parameters.items()},
        ex.stimuli,
        ex.references,
    )
    with tempfile.TemporaryDirectory(prefix="glider_lsref_") as tmp:
        unzipdir = fmpy.extract(str(fmu), unzipdir=tmp)
        data, note = simulate(fmu, md, unzipdir, planned)
    res = compare(planned, data, note, 0.0)
    if res.passed:
        return ""
    bad = max(
        res.variables,
        key=lambda v: v.max_error / v.tolerance if v.tolerance else math.inf,
        default=None,
    )
    if bad is None or bad.value is None:
        return note or "no outputs compared"
    return (
        f"{bad.name} = {bad.value:.10g} at t = {bad.time:g} s, loop {bad.reference:.10g} "
        f"(tolerance {ex.tolerance:g})" + (f"; {note}" if note else "")
    )


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m glider_cosim.verify.lsref_ours [--write | --check]``: (re)write our
    FMUs' LS-REF folders, or check that the shipped ones are what would be written."""
    import argparse
    import tempfile

    ap = argparse.ArgumentParser(
        prog="python -m glider_cosim.verify.lsref_ours",
        description="Write each component's FMI-LS-REF folder (src/<component>/lsref/, "
        "packed into its FMUs), or check that it is what would be written (exit 1 if not).",
    )
    group = ap.add_mutually_exclusive_group(required=True)
    group.add_argument("--write", action="store_true", help="rewrite the shipped folders")
    group.add_argument("--check", action="store_true", help="exit 1 if one is out of date")
    ap.add_argument("--component", default=None, help="one component (default: every one)")
    ap.add_argument("--fmu-dir", default=None, help="our FMUs (default: the per-user cache)")
    args = ap.parse_args(argv)
    try:
        models = cases_asked(args.component)
    except ValueError as err:
        ap.error(str(err))
    if args.write:
        for p in write_folders(args.fmu_dir, models=models):
            print(f"wrote {p}")
        return 0
    stale = []
    with tempfile.TemporaryDirectory(prefix="glider_lsref_") as tmp:
        write_folders(args.fmu_dir, Path(tmp), models)
        for model in models:
            shipped = shipped_folder(model)
            differ = [shipped / rel for rel in stale_files(Path(tmp) / model, shipped)]
            print(f"{shipped}: {'out of date' if differ else 'up to date'}")
            stale += differ
    for path in stale:
        print(f"{path}: out of date")
    return 1 if stale else 0


def stale_files(new: Path, shipped: Path) -> list[str]:
    """The files (relative paths) that differ between two LS-REF trees, or are in one only."""
    a = {p.relative_to(new).as_posix(): p for p in new.rglob("*") if p.is_file()}
    b = {p.relative_to(shipped).as_posix(): p for p in shipped.rglob("*") if p.is_file()}
    both = a.keys() | b.keys()
    return sorted(
        k for k in both if k not in a or k not in b or a[k].read_bytes() != b[k].read_bytes()
    )


if __name__ == "__main__":
    import sys

    sys.exit(main())
