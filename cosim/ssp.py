"""SSP 1.0 export and import of the glider system, and libcosim runs of an SSP.

``export_ssp`` writes an ``.ssp`` archive: ``SystemStructure.ssd`` (one ``ssd:Component``
per instance with its input and output ``ssd:Connector`` elements, the loop's
``ssd:Connection`` elements, the scenario's parameter values inline as
``ssv:ParameterSet``, ``ssd:DefaultExperiment`` with the stop time) and the FMUs under
``resources/``. The communication step is the annotation libcosim reads (its
``ssp_parser`` looks for it in the default experiment's annotations, nowhere else)::

    <ssd:DefaultExperiment startTime="0.0" stopTime="60.0">
      <ssd:Annotations>
        <ssc:Annotation type="com.opensimulationplatform">
          <osp:Algorithm><osp:FixedStepAlgorithm baseStepSize="0.02"/></osp:Algorithm>
        </ssc:Annotation>
      </ssd:Annotations>
    </ssd:DefaultExperiment>

(``osp`` = ``http://opensimulationplatform.com/SSP/OSPAnnotations``; libcosim matches the
prefixes ``ssd:``, ``ssc:``, ``ssv:``, ``osp:`` literally, so they are fixed here).

``load_ssp`` reads an ``.ssp`` archive, a ``.ssd`` file or a folder holding
``SystemStructure.ssd`` into our master's :class:`~glider_cosim.master.System`. Every
component, connector, connection and parameter is checked against the FMUs' model
descriptions before any FMU is instantiated; anything malformed or unsupported raises
:class:`SSPError` with one line naming the element. Unconnected Real inputs (our
``plant.F_x``, ``F_z``, ``M_y``) are driven with constants at their start value, or at
the value a parameter binding gives them, as libcosim leaves them.

``simulate_libcosim`` runs an SSP in libcosim (libcosimpy) and records variables at every
communication point. An FMU exception during libcosim's initialisation aborts the whole
process, so :func:`simulate_libcosim_isolated` runs it in a subprocess.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any
from xml.etree import ElementTree as ET

import numpy as np

from . import osp
from .inputs.archives import InputFileError, confined
from .inputs.ssp_files import SSD_NAME, SSPError, locate, parse_value
from .inputs.text import quote
from .master import System

if TYPE_CHECKING:
    from .runner import RunResult
    from .scenario import Scenario

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
}
for _prefix, _uri in NS.items():
    ET.register_namespace(_prefix, _uri)

OSP_ANNOTATION_TYPE = "com.opensimulationplatform"
#: our annotation on a component naming its OSP-IS model description in ``resources/``
OSP_MD_ANNOTATION_TYPE = "org.glider-cosim.osp-model-description"
OSP_MD_NS = "urn:glider-cosim:osp-model-description"
ET.register_namespace("gcosp", OSP_MD_NS)
FMU_MIME = "application/x-fmu-sharedlibrary"
_VALUE_TYPES = ("Real", "Integer", "Boolean")


def _q(prefix: str, tag: str) -> str:
    return f"{{{NS[prefix]}}}{tag}"


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _format_value(value: Any, type_: str) -> str:
    if type_ == "Real":
        return repr(float(value))
    if type_ == "Boolean":
        return "true" if bool(value) else "false"
    return str(int(value))


# --------------------------------------------------------------------------- export
def _as_fmi2_types(md: Any) -> Any:
    """An FMI 3.0 model description's Float64/Int32 variables as SSP 1.0's Real/Integer
    (the types an FMI 2.0 one declares); an FMI 2.0 one as it is."""
    from .fmi3_slave import TYPE_AS_FMI2

    if str(md.fmiVersion).startswith("3"):
        for v in md.modelVariables:
            v.type = TYPE_AS_FMI2.get(v.type, v.type)
    return md


def export_ssp(
    out_path: str | Path,
    scenario: Scenario | str | Path | None = None,
    fmu_dir: str | Path | None = None,
) -> Path:
    """Write a scenario's system as an SSP 1.0 archive.

    Parameters
    ----------
    out_path : path
        The ``.ssp`` file to write (its folder is created).
    scenario : Scenario, path, shipped name or None
        The scenario (``None``: the default). Its FMUs (swapped ones included),
        connections (``feedback``, ``with_observer``), per-instance parameters, constant
        inputs, step and stop time are exported; events and disturbances have no SSP 1.0
        equivalent and are refused.
    fmu_dir : path, optional
        Where our FMUs are (built there first if missing or stale; default: the per-user
        cache).

    Returns
    -------
    Path
        ``out_path``.

    Raises
    ------
    SSPError
        The scenario cannot be expressed in SSP 1.0, or names a variable the FMUs lack.
    """
    from fmpy import read_model_description

    from .build import build_all, fmu_folder
    from .runner import FMU_NAMES, default_connections
    from .scenario import Scenario, has_our_observer, load_scenario, with_sampling

    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if sc.events or sc.disturbances:
        key = "event" if sc.events else "disturbance"
        raise SSPError(
            f"{sc.source}: key '{key}': events and disturbances have no SSP 1.0 equivalent; "
            "export a scenario without them"
        )
    insts = [i for i in FMU_NAMES if sc.observer or i != "observer"]
    built = build_all(fmu_folder(fmu_dir), only_stale=True) if set(insts) - set(sc.fmus) else {}
    fmus: dict[str, Path] = {}
    for inst in insts:
        fmus[inst] = Path(sc.fmus[inst]) if inst in sc.fmus else built[FMU_NAMES[inst]]
    resources = {inst: f"resources/{fmu.name}" for inst, fmu in fmus.items()}
    if len(set(resources.values())) != len(resources):
        raise SSPError(f"{sc.source}: key 'fmus': two instances use FMU files of the same name")
    conns = default_connections(sc.feedback, sc.observer)
    ospmd = {}  # inst -> (path in the archive, content): beside its FMU, as OSP looks
    for inst, fmu in fmus.items():
        found = osp.read_from_fmu(fmu)
        if found is not None:
            ospmd[inst] = (f"resources/{Path(resources[inst]).stem}{osp.SUFFIX}", found[1])

    root = ET.Element(
        _q("ssd", "SystemStructureDescription"),
        {"version": "1.0", "name": f"glider-cosim-{sc.name}"},
    )
    system = ET.SubElement(root, _q("ssd", "System"), {"name": "glider"})
    elements = ET.SubElement(system, _q("ssd", "Elements"))
    comps = {}
    for inst in insts:
        md = _as_fmi2_types(read_model_description(str(fmus[inst])))
        variables = {v.name: v for v in md.modelVariables}
        comp = comps[inst] = ET.SubElement(
            elements,
            _q("ssd", "Component"),
            {"name": inst, "source": resources[inst], "type": FMU_MIME},
        )
        connectors = ET.SubElement(comp, _q("ssd", "Connectors"))
        for v in md.modelVariables:
            if v.causality in ("input", "output") and v.type in _VALUE_TYPES:
                c = ET.SubElement(
                    connectors, _q("ssd", "Connector"), {"name": v.name, "kind": v.causality}
                )
                ET.SubElement(c, _q("ssc", v.type))
        values = dict(
            with_sampling(sc.parameters, sc.step, sc.source, has_our_observer(sc)).get(inst, {})
        )
        for ref, value in sc.inputs.items():  # constant inputs: their start values
            if ref.startswith(f"{inst}."):
                values[ref.split(".", 1)[1]] = value
        if not values:
            continue
        bindings = ET.SubElement(comp, _q("ssd", "ParameterBindings"))
        binding = ET.SubElement(bindings, _q("ssd", "ParameterBinding"))
        pvalues = ET.SubElement(binding, _q("ssd", "ParameterValues"))
        pset = ET.SubElement(
            pvalues, _q("ssv", "ParameterSet"), {"version": "1.0", "name": f"{inst}-parameters"}
        )
        params = ET.SubElement(pset, _q("ssv", "Parameters"))
        for name, value in values.items():
            v = variables.get(name)
            if v is None or v.causality not in ("parameter", "input"):
                raise SSPError(
                    f"{sc.source}: key '{inst}.{name}': {fmus[inst].name} has no parameter or "
                    f"input '{name}'"
                )
            if v.type not in _VALUE_TYPES:
                raise SSPError(f"{sc.source}: key '{inst}.{name}': type {v.type} is not supported")
            p = ET.SubElement(params, _q("ssv", "Parameter"), {"name": name})
            ET.SubElement(p, _q("ssv", v.type), {"value": _format_value(value, v.type)})
    for inst, (path, _) in ospmd.items():  # Annotations come last in an ssd:Component
        annotation = ET.SubElement(
            ET.SubElement(comps[inst], _q("ssd", "Annotations")),
            _q("ssc", "Annotation"),
            {"type": OSP_MD_ANNOTATION_TYPE},
        )
        ET.SubElement(annotation, f"{{{OSP_MD_NS}}}OspModelDescription", {"source": path})
    connections = ET.SubElement(system, _q("ssd", "Connections"))
    for src, dst in conns:
        (se, sc_), (de, dc) = src.split(".", 1), dst.split(".", 1)
        ET.SubElement(
            connections,
            _q("ssd", "Connection"),
            {"startElement": se, "startConnector": sc_, "endElement": de, "endConnector": dc},
        )
    experiment = ET.SubElement(
        root,
        _q("ssd", "DefaultExperiment"),
        {"startTime": "0.0", "stopTime": repr(float(sc.stop_time))},
    )
    annotation = ET.SubElement(
        ET.SubElement(experiment, _q("ssd", "Annotations")),
        _q("ssc", "Annotation"),
        {"type": OSP_ANNOTATION_TYPE},
    )
    ET.SubElement(
        ET.SubElement(annotation, _q("osp", "Algorithm")),
        _q("osp", "FixedStepAlgorithm"),
        {"baseStepSize": repr(float(sc.step))},
    )
    ET.indent(root)
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr(SSD_NAME, ET.tostring(root, xml_declaration=True, encoding="UTF-8"))
        for inst in insts:
            z.write(fmus[inst], resources[inst])
        for path, content in dict(ospmd.values()).items():
            z.writestr(path, content)
    return out


# --------------------------------------------------------------------------- import
@dataclass
class _Component:
    name: str
    source: str
    fmu: Path
    variables: dict[str, Any]
    connectors: dict[str, str]


def _read_component(el: ET.Element, folder: Path, where: str) -> _Component:
    from .inputs.archives import read_fmu

    name, source = el.get("name"), el.get("source")
    if not name:
        raise SSPError(f"{where}: an ssd:Component has no name attribute")
    cwhere = f"{where}: component {quote(name)}"
    if "." in name:
        raise SSPError(f"{cwhere}: names with '.' are not supported (instance.variable)")
    if not source:
        raise SSPError(f"{cwhere}: no source attribute")
    if el.get("type", FMU_MIME) != FMU_MIME:
        raise SSPError(f"{cwhere}: type {el.get('type')!r} is not supported: expected {FMU_MIME}")
    if el.get("implementation", "CoSimulation") not in ("CoSimulation", "any"):
        raise SSPError(
            f"{cwhere}: implementation {el.get('implementation')!r} is not supported: "
            "expected CoSimulation"
        )
    try:
        fmu = confined(folder, source, cwhere)
    except InputFileError as err:
        raise SSPError(str(err)) from None
    if not fmu.exists():
        raise SSPError(f"{cwhere}: FMU {quote(source)} is missing")
    try:  # complete (binary, pythonfmu script) and readable; nothing loaded
        md = _as_fmi2_types(read_fmu(fmu, cwhere))
    except InputFileError as err:
        raise SSPError(str(err)) from None
    variables = {v.name: v for v in md.modelVariables}
    connectors: dict[str, str] = {}
    for c in el.iterfind("ssd:Connectors/ssd:Connector", NS):
        cname, kind = c.get("name"), c.get("kind")
        v = variables.get(cname)
        if v is None:
            raise SSPError(f"{cwhere}: connector '{cname}' is not a variable of {source}")
        if kind in ("input", "output", "parameter") and v.causality != kind:
            raise SSPError(
                f"{cwhere}: connector '{cname}' is declared {kind} but is {v.causality} in {source}"
            )
        types = [_local(t.tag) for t in c if _local(t.tag) in (*_VALUE_TYPES, "String")]
        if types and types[0] != v.type:
            raise SSPError(
                f"{cwhere}: connector '{cname}' is declared {types[0]} but is {v.type} in {source}"
            )
        connectors[cname] = kind or v.causality
    return _Component(name, source, fmu, variables, connectors)


def _read_parameters(
    el: ET.Element, comp: _Component, folder: Path, where: str
) -> dict[str, float | int | bool]:
    cwhere = f"{where}: component '{comp.name}'"
    values: dict[str, float | int | bool] = {}
    for binding in el.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
        if binding.find("ssd:ParameterMapping", NS) is not None:
            raise SSPError(f"{cwhere}: ssd:ParameterMapping is not supported")
        prefix = binding.get("prefix", "")
        source = binding.get("source")
        if source is not None:
            try:
                ssv = confined(folder, source, cwhere)
            except InputFileError as err:
                raise SSPError(str(err)) from None
            if not ssv.is_file():
                raise SSPError(f"{cwhere}: parameter values {quote(source)} are missing")
            try:
                pset = ET.parse(ssv).getroot()
            except ET.ParseError as err:
                raise SSPError(f"{cwhere}: '{source}' is not valid XML ({err})") from None
        else:
            pset = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
            if pset is None:
                raise SSPError(f"{cwhere}: a ssd:ParameterBinding has no source nor values")
        if pset.tag != _q("ssv", "ParameterSet"):
            raise SSPError(f"{cwhere}: parameter values are not an ssv:ParameterSet")
        for p in pset.iterfind("ssv:Parameters/ssv:Parameter", NS):
            name = prefix + (p.get("name") or "")
            pwhere = f"{cwhere}: parameter '{name}'"
            v = comp.variables.get(name)
            if v is None:
                raise SSPError(f"{pwhere} is not a variable of {comp.source}")
            if v.causality not in ("parameter", "input"):
                raise SSPError(f"{pwhere} has causality {v.causality}: expected parameter or input")
            typed = [t for t in p if _local(t.tag) != "Annotations"]
            if not typed:
                raise SSPError(f"{pwhere} has no value")
            tag = _local(typed[0].tag)
            if tag not in _VALUE_TYPES:
                raise SSPError(f"{pwhere}: ssv:{tag} values are not supported")
            if tag != v.type:
                raise SSPError(f"{pwhere} is given as {tag} but is {v.type} in {comp.source}")
            text = typed[0].get("value")
            if text is None:
                raise SSPError(f"{pwhere} has no value attribute")
            values[name] = parse_value(text.strip(), tag, pwhere)
    return values


def _read_step(root: ET.Element, where: str) -> float:
    algs = [
        alg
        for ann in root.iterfind("ssd:DefaultExperiment/ssd:Annotations/ssc:Annotation", NS)
        if ann.get("type") == OSP_ANNOTATION_TYPE
        for alg in ann.iterfind("osp:Algorithm/osp:FixedStepAlgorithm", NS)
    ]
    if not algs:
        raise SSPError(
            f"{where}: no osp:FixedStepAlgorithm baseStepSize in ssd:DefaultExperiment's "
            f"annotations (type '{OSP_ANNOTATION_TYPE}'): the communication step is missing"
        )
    text = algs[0].get("baseStepSize")
    try:
        step = float(text) if text is not None else math.nan
    except ValueError:
        step = math.nan
    if not (math.isfinite(step) and step > 0):
        raise SSPError(
            f"{where}: osp:FixedStepAlgorithm baseStepSize = {text!r} is invalid: expected a "
            "number > 0 (s)"
        )
    return step


def _read_stop_time(root: ET.Element, where: str) -> float:
    exp = root.find("ssd:DefaultExperiment", NS)
    if exp is None:
        raise SSPError(f"{where}: no ssd:DefaultExperiment (its stopTime is the run's end)")
    start, stop = exp.get("startTime", "0"), exp.get("stopTime")
    try:
        start_f = float(start)
    except ValueError:
        start_f = math.nan
    if start_f != 0.0:
        raise SSPError(f"{where}: ssd:DefaultExperiment startTime = {start!r}: only 0 is supported")
    try:
        stop_f = float(stop) if stop is not None else math.nan
    except ValueError:
        stop_f = math.nan
    if not (math.isfinite(stop_f) and stop_f > 0):
        raise SSPError(
            f"{where}: ssd:DefaultExperiment stopTime = {stop!r} is invalid: expected a "
            "number > 0 (s)"
        )
    return stop_f


def load_ssp(path: str | Path) -> tuple[System, float, float]:
    """Read an SSP into our master's :class:`~glider_cosim.master.System`.

    Parameters
    ----------
    path : path
        An ``.ssp`` archive (unpacked to a temporary folder, removed at exit), a
        ``.ssd`` file, or a folder holding ``SystemStructure.ssd``.

    Returns
    -------
    (System, float, float)
        The system (FMU paths, parameter values, connections, unconnected Real inputs
        driven at their start or bound value, every output recorded), the communication
        step from ``osp:FixedStepAlgorithm baseStepSize`` (s) and
        ``ssd:DefaultExperiment stopTime`` (s).

    Raises
    ------
    SSPError
        Missing or unreadable file or FMU, unknown component, connector or variable,
        connection that does not go from an output to an input of the same type,
        unsupported SSP feature, missing or non-positive step or stop time. Only model
        descriptions are read: no FMU is loaded or instantiated.
    """
    path = Path(path)
    where = str(path)
    folder, ssd = locate(path)
    if not ssd.is_file():
        raise SSPError(f"{where}: {SSD_NAME} is missing")
    try:
        root = ET.parse(ssd).getroot()
    except ET.ParseError as err:
        raise SSPError(f"{where}: {ssd.name} is not valid XML ({err})") from None
    if root.tag != _q("ssd", "SystemStructureDescription"):
        raise SSPError(
            f"{where}: the root element is not an SSP 1.0 ssd:SystemStructureDescription"
        )
    system = root.find("ssd:System", NS)
    if system is None:
        raise SSPError(f"{where}: no ssd:System element")
    if system.find("ssd:Elements/ssd:System", NS) is not None:
        raise SSPError(f"{where}: nested ssd:System elements (sub-systems) are not supported")
    if system.find("ssd:Elements/ssd:SignalDictionaryReference", NS) is not None:
        raise SSPError(f"{where}: ssd:SignalDictionaryReference is not supported")
    step = _read_step(root, where)
    stop_time = _read_stop_time(root, where)

    comps: dict[str, _Component] = {}
    values: dict[str, dict[str, float | int | bool]] = {}
    for el in system.iterfind("ssd:Elements/ssd:Component", NS):
        comp = _read_component(el, folder, where)
        if comp.name in comps:
            raise SSPError(f"{where}: component '{comp.name}' is defined twice")
        comps[comp.name] = comp
        values[comp.name] = _read_parameters(el, comp, folder, where)
    if not comps:
        raise SSPError(f"{where}: the system has no ssd:Component")

    connections: list[tuple[str, str]] = []
    sources: dict[str, str] = {}
    for c in system.iterfind("ssd:Connections/ssd:Connection", NS):
        se, sc_ = c.get("startElement"), c.get("startConnector")
        de, dc = c.get("endElement"), c.get("endConnector")
        cwhere = f"{where}: connection {se}.{sc_} -> {de}.{dc}"
        if se is None or de is None:
            raise SSPError(f"{cwhere}: connectors of the system itself are not supported")
        ends = []
        for element, connector, causality in ((se, sc_, "output"), (de, dc, "input")):
            comp = comps.get(element)
            if comp is None:
                raise SSPError(f"{cwhere}: unknown element '{element}'")
            v = comp.variables.get(connector)
            if v is None:
                raise SSPError(
                    f"{cwhere}: '{element}' ({comp.source}) has no variable '{connector}'"
                )
            if connector not in comp.connectors:
                raise SSPError(
                    f"{cwhere}: component '{element}' declares no connector '{connector}'"
                )
            if v.causality != causality:
                raise SSPError(
                    f"{cwhere}: {element}.{connector} is {v.causality}: expected {causality}"
                )
            ends.append(v)
        if ends[0].type != ends[1].type:
            raise SSPError(f"{cwhere}: type mismatch ({ends[0].type} -> {ends[1].type})")
        if any(_local(t.tag) != "Annotations" for t in c):
            raise SSPError(f"{cwhere}: transformations (ssc:...Transformation) are not supported")
        src, dst = f"{se}.{sc_}", f"{de}.{dc}"
        if dst in sources:
            raise SSPError(f"{cwhere}: input {dst} is already connected to {sources[dst]}")
        sources[dst] = src
        connections.append((src, dst))

    parameters: dict[str, dict[str, Any]] = {}
    driven: dict[str, float] = {}
    for name, comp in comps.items():
        for vname, v in comp.variables.items():
            ref = f"{name}.{vname}"
            if v.causality != "input" or ref in sources:
                continue
            if v.type != "Real":
                raise SSPError(
                    f"{where}: component '{name}': {v.type} input '{vname}' is unconnected: "
                    "only Real inputs can be driven by constants"
                )
            bound = values[name].pop(vname, None)
            start = bound if bound is not None else (v.start if v.start is not None else 0.0)
            driven[ref] = float(start)
        if values[name]:
            parameters[name] = values[name]
    system_ = System(
        fmus={n: c.fmu for n, c in comps.items()},
        connections=connections,
        parameters=parameters,
        driven=driven,
    )
    return system_, step, stop_time


def run_ssp(
    path: str | Path,
    out: str | Path | None = None,
    coupling: str = "gauss-seidel",
    *,
    stop_time: float | None = None,
    plots: bool = True,
) -> RunResult:
    """Run an SSP with our master (``glider-cosim run FILE.ssp``).

    Parameters
    ----------
    path : path
        ``.ssp`` archive, ``.ssd`` file or folder holding ``SystemStructure.ssd``.
    out : path, optional
        Results folder (``results.csv``, ``metrics.json``, plots); None keeps the rows in
        memory.
    coupling : str
        ``"gauss-seidel"`` or ``"jacobi"`` (SSP 1.0 has no coupling scheme; libcosim's
        fixed-step algorithm is ``"jacobi"``).
    stop_time : float, optional
        Overrides ``ssd:DefaultExperiment stopTime`` (s).
    plots : bool
        Write PNG plots (with ``out``).

    Returns
    -------
    glider_cosim.runner.RunResult
        As :func:`glider_cosim.runner.simulate`, with the step and stop time of the SSP.

    Raises
    ------
    SSPError
        The SSP is malformed (checked before any FMU is instantiated).
    """
    from .runner import simulate

    p = Path(path)
    if p.is_dir():
        p = p / SSD_NAME
    load_ssp(p)  # every check before any FMU runs
    return simulate(p, out, coupling=coupling, stop_time=stop_time, plots=plots, build=False)


# --------------------------------------------------------------------------- libcosim
@dataclass
class LibcosimRun:
    """Rows of a libcosim run: ``columns`` (``time`` first), ``data`` (one row per
    communication point, t0 included) and the wall time per macro step (s)."""

    columns: list[str]
    data: np.ndarray
    seconds_per_step: float

    def column(self, name: str) -> np.ndarray:
        """One column by name."""
        return self.data[:, self.columns.index(name)]


class LibcosimError(RuntimeError):
    """libcosim failed to load or run an SSP (its process died or a step failed)."""


def simulate_libcosim(
    path: str | Path, variables: Sequence[str], stop_time: float | None = None
) -> LibcosimRun:
    """Run an SSP in libcosim (libcosimpy, fixed-step algorithm) in this process.

    Real variables are recorded with libcosim's time-series observer at every
    communication point, the initial one included. An FMU exception during libcosim's
    initialisation aborts the process (uncatchable): use
    :func:`simulate_libcosim_isolated` unless the SSP is known to be good.

    Parameters
    ----------
    path : path
        ``.ssp`` archive, ``.ssd`` file or folder (checked with :func:`load_ssp` first).
    variables : sequence of str
        ``instance.variable`` names of Real variables to record.
    stop_time : float, optional
        End of the run (s); default the SSP's stop time.

    Returns
    -------
    LibcosimRun
        The rows and the wall time per macro step.

    Raises
    ------
    SSPError
        The SSP is malformed or a variable is unknown.
    LibcosimError
        libcosim could not create the execution or a step failed.
    """
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    system, step, stop = load_ssp(path)
    stop = stop if stop_time is None else float(stop_time)
    n = round(stop / step)
    log_output_level(CosimLogLevel.ERROR)
    try:
        ex = CosimExecution.from_ssp_file(str(path))
    except AssertionError:  # libcosimpy asserts on a null execution
        raise LibcosimError(f"{path}: libcosim could not create an execution from it") from None
    observer = CosimObserver.create_time_series()
    ex.add_observer(observer)
    refs = []
    for name in variables:
        inst, _, var = name.partition(".")
        if inst not in system.fmus:
            raise SSPError(f"{path}: variable '{name}': no component '{inst}'")
        idx = ex.slave_index_from_instance_name(inst)
        vr = next((v.reference for v in ex.slave_variables(idx) if v.name.decode() == var), None)
        if vr is None:
            raise SSPError(f"{path}: variable '{name}': '{inst}' has no variable '{var}'")
        observer.start_time_series(idx, vr, CosimVariableType.REAL)
        refs.append((idx, vr))
    t0 = time.perf_counter()
    if not ex.step(n):
        raise LibcosimError(f"{path}: libcosim's step failed before t = {stop:g} s")
    seconds = (time.perf_counter() - t0) / max(n, 1)
    columns = ["time", *variables]
    data = np.empty((n + 1, len(columns)))
    data[:, 0] = np.arange(n + 1) * step
    for j, (idx, vr) in enumerate(refs, start=1):
        # libcosimpy 0.0.6 returns at most (last step - from_step) samples per call: the
        # last one comes with a second call
        steps: list[int] = []
        for _ in range(3):
            if len(steps) == n + 1:
                break
            times, got, values = observer.time_series_real_samples(
                idx, vr, len(steps), n + 1 - len(steps)
            )
            for k, t_ns, value in zip(got, times, values):
                data[k, 0], data[k, j] = t_ns * 1e-9, value
            steps += list(got)
        if steps != list(range(n + 1)):
            raise LibcosimError(f"{path}: libcosim recorded {len(steps)} of {n + 1} samples")
    return LibcosimRun(columns, data, seconds)


def simulate_libcosim_isolated(
    path: str | Path,
    variables: Sequence[str],
    stop_time: float | None = None,
    timeout: float = 600.0,
) -> LibcosimRun:
    """:func:`simulate_libcosim` in a subprocess (libcosim may abort or crash its process).

    Parameters
    ----------
    path, variables, stop_time
        As :func:`simulate_libcosim`.
    timeout : float
        Seconds before the subprocess is killed.

    Returns
    -------
    LibcosimRun
        The rows and the wall time per macro step.

    Raises
    ------
    SSPError
        The SSP is malformed (checked in this process first).
    LibcosimError
        The subprocess failed, died or timed out (its last message is included).
    """
    load_ssp(path)
    args = [str(path), json.dumps(list(variables)), json.dumps(stop_time)]
    try:
        p = subprocess.run(
            [sys.executable, "-m", "glider_cosim.ssp", *args],
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        raise LibcosimError(f"{path}: libcosim did not finish within {timeout:g} s") from None
    lines = p.stdout.strip().splitlines()
    if p.returncode != 0 or not lines:
        last = (p.stderr.strip().splitlines() or [f"exit code {p.returncode}"])[-1]
        raise LibcosimError(f"{path}: libcosim failed (exit code {p.returncode}): {last}")
    result = json.loads(lines[-1])
    return LibcosimRun(result["columns"], np.array(result["data"]), result["seconds_per_step"])


def _main(argv: Sequence[str]) -> int:
    """Subprocess entry of :func:`simulate_libcosim_isolated` (JSON on stdout)."""
    path, variables, stop_time = argv[0], json.loads(argv[1]), json.loads(argv[2])
    try:
        run = simulate_libcosim(path, variables, stop_time)
    except (SSPError, LibcosimError) as err:
        print(err, file=sys.stderr)
        return 1
    out = {
        "columns": run.columns,
        "data": run.data.tolist(),
        "seconds_per_step": run.seconds_per_step,
    }
    print(json.dumps(out))
    return 0


if __name__ == "__main__":  # pragma: no cover - run by simulate_libcosim_isolated
    sys.exit(_main(sys.argv[1:]))
