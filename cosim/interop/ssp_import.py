"""Read an SSP into our master's :class:`~glider_cosim.master.System`, checked against the FMUs."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from ..inputs.archives import InputFileError, confined
from ..inputs.ssp_files import SSD_NAME, SSPError, locate, parse_value
from ..inputs.text import quote
from ..master.spec import System
from .ssp_common import (
    FMU_MIME,
    NS,
    OSP_ANNOTATION_TYPE,
    VALUE_TYPES,
    as_fmi2_types,
    local_name,
    qname,
)


# --------------------------------------------------------------------------- import
@dataclass
class _Component:
    name: str
    source: str
    fmu: Path
    variables: dict[str, Any]
    connectors: dict[str, str]


def _read_component(el: ET.Element, folder: Path, where: str) -> _Component:
    from ..inputs.archives import read_fmu

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
        md = as_fmi2_types(read_fmu(fmu, cwhere))
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
        types = [local_name(t.tag) for t in c if local_name(t.tag) in (*VALUE_TYPES, "String")]
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
        if pset.tag != qname("ssv", "ParameterSet"):
            raise SSPError(f"{cwhere}: parameter values are not an ssv:ParameterSet")
        for p in pset.iterfind("ssv:Parameters/ssv:Parameter", NS):
            name = prefix + (p.get("name") or "")
            pwhere = f"{cwhere}: parameter '{name}'"
            v = comp.variables.get(name)
            if v is None:
                raise SSPError(f"{pwhere} is not a variable of {comp.source}")
            if v.causality not in ("parameter", "input"):
                raise SSPError(f"{pwhere} has causality {v.causality}: expected parameter or input")
            typed = [t for t in p if local_name(t.tag) != "Annotations"]
            if not typed:
                raise SSPError(f"{pwhere} has no value")
            tag = local_name(typed[0].tag)
            if tag not in VALUE_TYPES:
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
    if root.tag != qname("ssd", "SystemStructureDescription"):
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
        if any(local_name(t.tag) != "Annotations" for t in c):
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
