"""FMI-LS-REF in every FMU we build: experiments, parameter sets and documents that travel
inside the FMU (``extra/org.fmi-standard.fmi-ls-ref/``).

The layered standard FMI-LS-REF (modelica/fmi-ls-ref, version 1.0.0-alpha.1) lists an
FMU's related files in ``extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml``, each
``<Related>`` with a ``source`` (relative to the manifest), a ``role`` and a MIME
``type``. Experiments are files in the MA-HS-Experiments format (modelica/ma-hs-
experiments, ``application/x-ma-hs-experiments``): ``<Experiment name tolerance>``
with a ``<TransientSimulation startTime stopTime stepSize>``, optional ``<Parameters>``
(an SSV file), ``<Stimuli>`` and ``<References>`` (CSV files).

What the standards leave open, and what glider-cosim writes and reads
(docs/how-to/verify-a-component.md, "FMUs that carry their own tests"):

- **CSV layout**: a header ``time,<variable>,...`` (variables by their names in the
  model description), then one row per time, numbers as Python's ``repr`` writes them
  (exact).
- **Stimuli** are held: each row's values are set from its time until the next row's
  time (sample and hold), at the communication points ``start + k * step``.
- **References** are compared at each of their rows' times, which are communication
  points; the outputs are read after the inputs of that point are set (so an output
  that depends directly on an input sees the input of the same row).
- **tolerance** ``tol`` (a number >= 0): a value passes if
  ``|y - y_ref| <= tol * (1 + |y_ref|)``, i.e. an absolute tolerance ``tol`` near zero
  and a relative one ``tol`` for large values. An experiment without one is compared
  at :data:`DEFAULT_TOLERANCE`.
- **Checksums**: the standard's ``<Related>`` has no checksum attribute (fmi-ls-ref
  at ``baf43cc``), so each entry carries its file's SHA3-256 in its ``<Annotations>``:
  ``<Annotation type="org.glider-cosim.checksum"><gc:Checksum algorithm="SHA3-256"
  value="..."/></Annotation>`` (:data:`CHECKSUM_TYPE`, :data:`CHECKSUM_NS`), valid by
  the standard's ``fmi3Annotation.xsd``.

Our three FMUs carry (:func:`entries`):

- ``smoke-test.exp`` (role ``experiment/smoke-test``): the component's reference case,
  ``src/<component>/reference_input.csv`` and ``reference_output.csv`` with its
  parameters (:mod:`glider_cosim.verify.reference`);
- ``validation.exp`` (``experiment/validation``): the paper's default start (Sec. 3.3,
  60 s), component level: the component's inputs recorded from a run of the loop as
  stimuli, its outputs as references, the scenario's values of its parameters
  (``python -m glider_cosim.fmus.lsref --write`` records them into
  ``verification/lsref/<component>/``);
- ``parameters/<scenario>.ssv`` (``parameter``): each shipped scenario's values of the
  component's parameters that differ from its start values (the limit cycle at
  K_c = 6, the paper's PI and P gains, the tail angles, ...);
- ``README.md`` (``document``): the component's readme, its equations.
"""

from __future__ import annotations

import functools
import hashlib
import math
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np

#: the folder of the layered standard in an FMU
LSREF_DIR = "extra/org.fmi-standard.fmi-ls-ref"
#: the manifest (the standard's fixed name)
MANIFEST = f"{LSREF_DIR}/fmi-ls-manifest.xml"
LS_NAME = "org.fmi-standard.fmi-ls-ref"
LS_VERSION = "1.0.0-alpha.1"
#: fixed by the schema
LS_DESCRIPTION = "Layered Standard providing information on related files included in an FMU."
LS_NS = "http://fmi-standard.org/fmi-ls-manifest"
EXPERIMENTS_MIME = "application/x-ma-hs-experiments"
SSV_MIME = "application/x-ssp-parameter-set"
#: the annotation carrying an entry's checksum, and its element's namespace
CHECKSUM_TYPE = "org.glider-cosim.checksum"
CHECKSUM_NS = "urn:glider-cosim:checksum"
#: the checksum algorithm written (Python's ``hashlib.sha3_256``)
CHECKSUM_ALGORITHM = "SHA3-256"
#: the tolerance of an experiment that gives none
DEFAULT_TOLERANCE = 1e-6
#: the tolerance of our FMUs' smoke test (the reference case: round-off only)
SMOKE_TOLERANCE = 1e-9
#: the tolerance of our FMUs' validation (the loop's values replayed: round-off only)
VALIDATION_TOLERANCE = 1e-9

ET.register_namespace("fmi-ls", LS_NS)
ET.register_namespace("gc", CHECKSUM_NS)


class LsrefError(ValueError):
    """An LS-REF manifest or experiment cannot be written or read (one line naming the
    file and what is wrong)."""


def sha3(data: bytes) -> str:
    """The SHA3-256 of ``data`` (hex), the checksum of every entry."""
    return hashlib.sha3_256(data).hexdigest()


# ------------------------------------------------------------------ what is written
@dataclass
class Experiment:
    """One transient experiment: its settings, parameters, stimuli and references.

    ``stimuli``/``references``: (columns, rows), ``time`` first; ``parameters``: name ->
    value (float, int or bool), written as an SSV file when not empty.
    """

    name: str
    description: str
    start: float
    stop: float
    step: float
    tolerance: float
    references: tuple[list[str], np.ndarray]
    stimuli: tuple[list[str], np.ndarray] | None = None
    parameters: dict[str, Any] = field(default_factory=dict)


@dataclass
class Related:
    """One ``<Related>`` entry: its file (path relative to the manifest) and bytes."""

    source: str
    role: str
    type: str
    description: str
    data: bytes
    labels: tuple[tuple[str, str], ...] = ()


def table_bytes(columns: Sequence[str], data: np.ndarray) -> bytes:
    """A CSV table: header, then each number in its shortest exact form (``repr``)."""
    lines = [",".join(columns)]
    lines += [",".join(repr(float(v)) for v in row) for row in np.asarray(data, dtype=float)]
    return ("\n".join(lines) + "\n").encode()


def _xml(root: ET.Element) -> bytes:
    ET.indent(root, "  ")
    text = ET.tostring(root, "unicode")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + text.encode() + b"\n"


def ssv_bytes(name: str, values: Mapping[str, Any], types: Mapping[str, str], fmi: int) -> bytes:
    """An SSV parameter set (SSP 1.0's types for an FMI 2.0 FMU, SSP 2.0's for FMI 3.0).

    ``types``: variable name -> its FMI type in the model description (``Real``,
    ``Float64``, ``Integer``, ``Int32``, ``Boolean``)."""
    from ..interop.ssp_common import as_ssp1_type, format_value, qname

    version = "2.0" if fmi == 3 else "1.0"
    root = ET.Element(qname("ssv", "ParameterSet"), {"version": version, "name": name})
    params = ET.SubElement(root, qname("ssv", "Parameters"))
    for var, value in values.items():
        kind = types.get(var)
        if kind is None or as_ssp1_type(kind) not in ("Real", "Integer", "Boolean"):
            raise LsrefError(
                f"parameter set {name!r}: {var!r} is not a Real, Integer or "
                "Boolean variable of the FMU"
            )
        tag = kind if fmi == 3 else as_ssp1_type(kind)
        p = ET.SubElement(params, qname("ssv", "Parameter"), {"name": var})
        ET.SubElement(p, qname("ssv", tag), {"value": format_value(value, kind)})
    return _xml(root)


def experiments_bytes(
    name: str, description: str, experiments: Sequence[tuple[Experiment, dict]]
) -> bytes:
    """An MA-HS-Experiments file; each experiment with its files' names (``parameters``,
    ``stimuli``, ``references``: paths relative to this file)."""
    root = ET.Element("Experiments", {"name": name, "description": description})
    for ex, files in experiments:
        el = ET.SubElement(
            root,
            "Experiment",
            {
                "name": ex.name,
                "description": ex.description,
                "tolerance": repr(float(ex.tolerance)),
            },
        )
        ET.SubElement(
            el,
            "TransientSimulation",
            {
                "startTime": repr(float(ex.start)),
                "stopTime": repr(float(ex.stop)),
                "stepSize": repr(float(ex.step)),
            },
        )
        for tag, key, mime in (
            ("Parameters", "parameters", SSV_MIME),
            ("Stimuli", "stimuli", "text/csv"),
            ("References", "references", "text/csv"),
        ):
            if key in files:
                ET.SubElement(el, tag, {"type": mime, "source": files[key]})
    return _xml(root)


def experiment_files(
    folder: str,
    experiments: Sequence[Experiment],
    types: Mapping[str, str],
    fmi: int,
    role: str,
    title: str,
    description: str,
) -> list[Related]:
    """The entries of an experiments file ``<folder>.exp`` and the files it names
    (``<folder>/<experiment>-parameters.ssv``, ``-stimuli.csv``, ``-references.csv``)."""
    out: list[Related] = []
    listed = []
    for ex in experiments:
        files = {}
        if ex.parameters:
            files["parameters"] = f"{folder}/{ex.name}-parameters.ssv"
            out.append(
                Related(
                    files["parameters"],
                    "parameter",
                    SSV_MIME,
                    f"parameters of the {title} experiment {ex.name!r}",
                    ssv_bytes(f"{folder}-{ex.name}", ex.parameters, types, fmi),
                    (("experiment", f"{folder}.exp#{ex.name}"),),
                )
            )
        if ex.stimuli is not None:
            files["stimuli"] = f"{folder}/{ex.name}-stimuli.csv"
            out.append(
                Related(
                    files["stimuli"],
                    "testcase",
                    "text/csv",
                    f"stimuli of the {title} experiment {ex.name!r} (held)",
                    table_bytes(*ex.stimuli),
                )
            )
        files["references"] = f"{folder}/{ex.name}-references.csv"
        out.append(
            Related(
                files["references"],
                "result",
                "text/csv",
                f"references of the {title} experiment {ex.name!r}",
                table_bytes(*ex.references),
            )
        )
        listed.append((ex, files))
    exp = Related(
        f"{folder}.exp",
        role,
        EXPERIMENTS_MIME,
        description,
        experiments_bytes(title, description, listed),
    )
    return [exp, *out]


def manifest_bytes(related: Sequence[Related]) -> bytes:
    """The manifest listing ``related``, each with its SHA3-256 (:data:`CHECKSUM_TYPE`)."""
    ls = f"{{{LS_NS}}}"
    root = ET.Element(
        "fmiReferences",
        {
            f"{ls}fmi-ls-name": LS_NAME,
            f"{ls}fmi-ls-version": LS_VERSION,
            f"{ls}fmi-ls-description": LS_DESCRIPTION,
        },
    )
    for r in related:
        el = ET.SubElement(
            root,
            "Related",
            {"type": r.type, "source": r.source, "role": r.role, "description": r.description},
        )
        for label, value in r.labels:
            ET.SubElement(el, "Label", {"name": f"{label}:{value}"})
        note = ET.SubElement(
            ET.SubElement(el, "Annotations"), "Annotation", {"type": CHECKSUM_TYPE}
        )
        ET.SubElement(
            note,
            f"{{{CHECKSUM_NS}}}Checksum",
            {"algorithm": CHECKSUM_ALGORITHM, "value": sha3(r.data)},
        )
    return _xml(root)


def zip_entries(related: Sequence[Related]) -> dict[str, bytes]:
    """Zip path -> bytes: the manifest and every file it lists."""
    out = {f"{LSREF_DIR}/{r.source}": r.data for r in related}
    out[MANIFEST] = manifest_bytes(related)
    return out


# ------------------------------------------------------------------ our three FMUs
#: model name -> component (the verification kit's name)
OURS = {"GliderPlant": "plant", "GliderObserver": "observer", "GliderController": "controller"}
#: the scenario the validation experiment is recorded from
VALIDATION_SCENARIO = "default"


def _package_dir(component: str) -> Path:
    import importlib

    return Path(importlib.import_module(f"glider_{component}").__file__).resolve().parent


def validation_root() -> Path:
    """Where the validation experiments' recorded files are (in the installed package)."""
    from ..verify.cases import kit_root

    return kit_root() / "lsref"


def _data_files() -> list[Path]:
    """Every file our FMUs' LS-REF entries are made from (their fingerprint)."""
    from importlib import resources

    files = [Path(__file__)]
    for component in OURS.values():
        pkg = _package_dir(component)
        files += [pkg / "reference_input.csv", pkg / "reference_output.csv", pkg / "README.md"]
        files += sorted((validation_root() / component).glob("*"))
    files += sorted(Path(str(resources.files("glider_cosim") / "scenarios")).glob("*.toml"))
    return files


def fingerprint() -> str:
    """Hash of this module and the files it packs: part of the cache's sources key and of
    the Python FMUs' source hash (a change rebuilds them)."""
    files = _data_files()
    return _fingerprint(tuple((str(f), f.stat().st_mtime_ns, f.stat().st_size) for f in files))


@functools.lru_cache(maxsize=8)
def _fingerprint(stamp: tuple[tuple[str, int, int], ...]) -> str:
    h = hashlib.sha256()
    for path, _, _ in stamp:
        h.update(Path(path).name.encode())
        h.update(Path(path).read_bytes())
    return h.hexdigest()


def variable_types(md_xml: bytes) -> tuple[str, int, dict[str, str], dict[str, str]]:
    """(model name, FMI version 2 or 3, name -> FMI type, name -> start text) of a model
    description."""
    root = ET.fromstring(md_xml)
    fmi = 3 if root.get("fmiVersion", "").startswith("3") else 2
    types: dict[str, str] = {}
    starts: dict[str, str] = {}
    mv = root.find("ModelVariables")
    for v in mv if mv is not None else ():
        name = v.get("name")
        if fmi == 2:
            typed = next(iter(v), None)
            if typed is None:
                continue
            types[name] = typed.tag
            if typed.get("start") is not None:
                starts[name] = typed.get("start")
        else:
            types[name] = v.tag
            if v.get("start") is not None:
                starts[name] = v.get("start")
    return root.get("modelName", ""), fmi, types, starts


def _differs(value: Any, start: str | None) -> bool:
    if start is None:
        return True
    if isinstance(value, bool):
        return value != (start.strip().lower() in ("true", "1"))
    try:
        return not math.isclose(float(value), float(start), rel_tol=0.0, abs_tol=0.0)
    except ValueError:
        return True


def scenario_sets(component: str, starts: Mapping[str, str]) -> list[tuple[str, str, dict]]:
    """(scenario name, summary, values) of each shipped scenario whose values of the
    component's parameters differ from the FMU's start values (only those values)."""
    from ..scenarios.sampling import with_sampling
    from ..scenarios.scenario import load_scenario, one_line_summary, shipped_scenarios

    out = []
    for name in shipped_scenarios():
        sc = load_scenario(name)
        if component == "observer" and not sc.observer:
            continue
        params = with_sampling(
            sc.parameters, sc.step, sc.source, component != "observer" or sc.observer
        ).get(component, {})
        values = {k: v for k, v in params.items() if _differs(v, starts.get(k))}
        if values:
            out.append((name, one_line_summary(sc, 200), values))
    return out


def smoke_experiment(model: str) -> Experiment:
    """The component's reference case (``src/<component>/reference_*.csv``)."""
    from ..verify.cases import read_table
    from ..verify.reference import CASES, STEP, STOP

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


def validation_experiment(model: str) -> Experiment:
    """The paper's default start, component level (recorded by :func:`write_validation`)."""
    from ..verify.cases import load_case

    case = load_case(OURS[model], VALIDATION_SCENARIO, validation_root())
    assert case.reference is not None
    return Experiment(
        VALIDATION_SCENARIO,
        f"{model} in the loop of the paper's default scenario (Sec. 3.3, {case.stop:g} s): its "
        "inputs recorded from a run of the loop, its outputs as references",
        case.start,
        case.stop,
        case.step,
        VALIDATION_TOLERANCE,
        (case.ref_columns, case.reference),
        (case.input_columns, case.inputs),
        {k: _typed_text(v) for k, v in case.parameters.items()},
    )


def _typed_text(text: str) -> float | int | bool:
    t = text.strip().lower()
    if t in ("true", "false"):
        return t == "true"
    try:
        return int(t)
    except ValueError:
        return float(t)


def entries(md_xml: bytes) -> dict[str, bytes]:
    """Zip path -> bytes of the LS-REF folder of one of our FMUs (from its model
    description: its name, FMI version, types and start values); empty for a model that
    is not ours. One function for every flavor and FMI version."""
    model, fmi, types, starts = variable_types(md_xml)
    if model not in OURS:
        return {}
    return dict(
        _entries(
            model, fmi, tuple(sorted(types.items())), tuple(sorted(starts.items())), fingerprint()
        )
    )


@functools.lru_cache(maxsize=16)
def _entries(model: str, fmi: int, types: tuple, starts: tuple, _key: str) -> tuple:
    component = OURS[model]
    types_d, starts_d = dict(types), dict(starts)
    related = experiment_files(
        "smoke-test",
        [smoke_experiment(model)],
        types_d,
        fmi,
        "experiment/smoke-test",
        f"{model} smoke test",
        f"{model}: the reference case of glider-cosim's {component}",
    )
    if (validation_root() / component / f"{VALIDATION_SCENARIO}_ref.opt").is_file():
        related += experiment_files(
            "validation",
            [validation_experiment(model)],
            types_d,
            fmi,
            "experiment/validation",
            f"{model} validation",
            f"{model}: the paper's default start, component level",
        )
    for name, summary, values in scenario_sets(component, starts_d):
        related.append(
            Related(
                f"parameters/{name}.ssv",
                "parameter",
                SSV_MIME,
                f"scenario {name}: {summary}",
                ssv_bytes(name, values, types_d, fmi),
                (("scenario", name),),
            )
        )
    readme = _package_dir(component) / "README.md"
    related.append(
        Related(
            "README.md",
            "document",
            "text/markdown",
            f"{model}: the component's readme (model, equations, variables)",
            readme.read_bytes(),
        )
    )
    return tuple(zip_entries(related).items())


def add_to_fmu(fmu: Path) -> None:
    """Add the LS-REF folder to ``fmu`` (one of ours, from its own model description;
    nothing for another model); the FMU must not carry one yet."""
    with zipfile.ZipFile(fmu, "a", zipfile.ZIP_DEFLATED) as z:
        for path, data in entries(z.read("modelDescription.xml")).items():
            z.writestr(path, data)


def is_current(z: zipfile.ZipFile) -> bool:
    """True if the FMU open in ``z`` carries the LS-REF manifest its model description
    asks for now (always true for a model that is not ours)."""
    want = entries(z.read("modelDescription.xml")).get(MANIFEST)
    if want is None:
        return True
    try:
        return z.read(MANIFEST) == want
    except KeyError:
        return False


# ------------------------------------------------------------------ recording a loop
def record_component(scenario: Any, instance: str, fmu_dir: Path) -> Experiment:
    """Run ``scenario``'s loop with our master and record one instance at component level:
    its inputs (connected or driven) as stimuli, its outputs as references, the values the
    scenario gives its parameters. Every input is recorded as it is set before each step,
    so the instance alone on these stimuli steps through the same values."""
    from fmpy import read_model_description

    from ..master.cosimulation import CoSimulation
    from ..runner.recorders import ArrayRecorder
    from ..scenarios.system import system_for

    system = system_for(scenario, Path(fmu_dir), scenario.step)
    md = read_model_description(str(system.fmus[instance]))
    md_vars = {v.name: v.causality for v in md.modelVariables}
    inputs = [n for n, c in md_vars.items() if c == "input"]
    outputs = [n for n, c in md_vars.items() if c == "output"]
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
    # A row holds an input as it was when the row was read; with Gauss-Seidel coupling an
    # instance stepped after the one feeding it has already used the next row's value
    # over a step. The stimuli are the values each step used: the alignment (this row's
    # or the next row's values) with which the instance alone reproduces its outputs.
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
        worst = replay_differs(system.fmus[instance], md, ex)
        if not worst:
            return ex
    raise LsrefError(
        f"{instance} ({Path(system.fmus[instance]).name}) alone on the inputs recorded from "
        f"the loop does not reproduce its outputs there: {worst}"
    )


def replay_differs(fmu: Path, md: Any, ex: Experiment) -> str:
    """Run ``ex`` on ``fmu`` with the verifier's runner (fmpy); empty if it passes, else
    its worst variable in words."""
    import tempfile

    import fmpy

    from ..verify.lsref import Planned, compare, simulate

    kinds = {v.name: v.type for v in md.modelVariables}
    planned = Planned(
        "<recorded>",
        "experiment",
        ex.name,
        ex.tolerance,
        ex.start,
        ex.stop,
        ex.step,
        {k: (kinds[k], _value_text(v)) for k, v in ex.parameters.items()},
        ex.stimuli,
        ex.references,
    )
    with tempfile.TemporaryDirectory(prefix="glider_lsref_") as tmp:
        unzipdir = fmpy.extract(str(fmu), unzipdir=tmp)
        data, note = simulate(Path(fmu), md, unzipdir, planned)
    res = compare(planned, data, note, 0.0)
    if res.passed:
        return ""
    bad = max(
        res.variables, key=lambda v: v.max_error / v.tolerance if v.tolerance else 0.0, default=None
    )
    if bad is None:
        return note or "no outputs compared"
    return (
        f"{bad.name} = {bad.value:.10g} at t = {bad.time:g} s, loop {bad.reference:.10g} "
        f"(tolerance {ex.tolerance:g})" + (f"; {note}" if note else "")
    )


def write_validation(fmu_dir: str | Path | None = None) -> list[Path]:
    """Record the validation experiment of each of our components from the default loop
    into ``verification/lsref/<component>/`` (the kit's case files:
    ``default_in.csv``, ``default_par.csv``, ``default_ref.csv``, ``default_ref.opt``)."""
    from ..scenarios.scenario import load_scenario
    from .folders import build_all, fmu_folder

    folder = fmu_folder(fmu_dir)
    build_all(folder, only_stale=True)
    sc = load_scenario(VALIDATION_SCENARIO)
    written = []
    for component in OURS.values():
        ex = record_component(sc, component, folder)
        out = validation_root() / component
        out.mkdir(parents=True, exist_ok=True)
        name = VALIDATION_SCENARIO
        files = {
            f"{name}_in.csv": table_bytes(*ex.stimuli) if ex.stimuli else b"",
            f"{name}_ref.csv": table_bytes(*ex.references),
            f"{name}_par.csv": (
                "name,value\n"
                + "".join(f"{k},{_value_text(v)}\n" for k, v in ex.parameters.items())
            ).encode(),
            f"{name}_ref.opt": (
                f"StartTime, {ex.start!r}\nStopTime, {ex.stop!r}\n"
                f"StepSize, {ex.step!r}\nRelTol, {ex.tolerance!r}\n"
                f"AbsTol, {ex.tolerance!r}\n"
            ).encode(),
        }
        for fname, data in files.items():
            (out / fname).write_bytes(data)
            written.append(out / fname)
    return written


def _value_text(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    return repr(float(v))


def read_manifest_bytes(fmu: Path) -> bytes | None:
    """The LS-REF manifest ``fmu`` carries, None if none."""
    with zipfile.ZipFile(fmu) as z:
        try:
            return z.read(MANIFEST)
        except KeyError:
            return None


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m glider_cosim.fmus.lsref --write``: record the validation experiments."""
    import argparse

    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--write", action="store_true", help="rewrite the recorded files")
    ap.add_argument("--fmu-dir", default=None, help="our FMUs (default: the per-user cache)")
    args = ap.parse_args(argv)
    if args.write:
        for p in write_validation(args.fmu_dir):
            print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main())
