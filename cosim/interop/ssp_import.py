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
    OMS_ANNOTATION_TYPE,
    OSP_ANNOTATION_TYPE,
    SSD_VERSIONS,
    VALUE_TYPES,
    as_fmi2_types,
    as_ssp1_type,
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
    #: the FMU's own ``DefaultExperiment stepSize`` (s), if it gives one
    step_size: str | None = None


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
        types = [
            as_ssp1_type(local_name(t.tag))
            for t in c
            if as_ssp1_type(local_name(t.tag)) in (*VALUE_TYPES, "String")
        ]
        if types and types[0] != v.type:
            raise SSPError(
                f"{cwhere}: connector '{cname}' is declared {types[0]} but is {v.type} in {source}"
            )
        connectors[cname] = kind or v.causality
    exp = md.defaultExperiment
    step_size = None if exp is None or exp.stepSize is None else str(exp.stepSize)
    return _Component(name, source, fmu, variables, connectors, step_size)


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
            tag = as_ssp1_type(local_name(typed[0].tag))
            if tag not in VALUE_TYPES:
                raise SSPError(f"{pwhere}: ssv:{tag} values are not supported")
            if tag != v.type:
                raise SSPError(f"{pwhere} is given as {tag} but is {v.type} in {comp.source}")
            text = typed[0].get("value")
            if text is None:
                raise SSPError(f"{pwhere} has no value attribute")
            values[name] = parse_value(text.strip(), tag, pwhere)
    return values


def _positive(text: str | None) -> float:
    """A step or stop time's text as a finite number > 0, or NaN."""
    try:
        value = float(text) if text is not None else math.nan
    except ValueError:
        return math.nan
    return value if math.isfinite(value) and value > 0 else math.nan


def _read_step(root: ET.Element, comps: dict[str, _Component], where: str) -> float:
    """The communication step (s) of an SSP, wherever the tool that wrote it put it:
    the OSP annotation of ``ssd:DefaultExperiment`` (ours, libcosim's), OMSimulator's
    ``oms:FixedStepMaster stepSize`` on the top ``ssd:System``, or else the FMUs' own
    ``DefaultExperiment stepSize`` when every FMU that gives one gives the same."""
    found = [
        ("osp:FixedStepAlgorithm baseStepSize", alg.get("baseStepSize"))
        for ann in root.iterfind("ssd:DefaultExperiment/ssd:Annotations/ssc:Annotation", NS)
        if ann.get("type") == OSP_ANNOTATION_TYPE
        for alg in ann.iterfind("osp:Algorithm/osp:FixedStepAlgorithm", NS)
    ] + [
        ("oms:FixedStepMaster stepSize", master.get("stepSize"))
        for ann in root.iterfind("ssd:System/ssd:Annotations/ssc:Annotation", NS)
        if ann.get("type") == OMS_ANNOTATION_TYPE
        for master in ann.iterfind(".//oms:SimulationInformation/oms:FixedStepMaster", NS)
    ]
    if found:
        what, text = found[0]
        step = _positive(text)
        if math.isnan(step):
            raise SSPError(
                f"{where}: {what} = {text!r} is invalid: expected a number > 0 (s), or give "
                "one with --step"
            )
        return step
    given = {c.name: c.step_size for c in comps.values() if c.step_size is not None}
    steps = {_positive(text) for text in given.values()}
    if len(steps) == 1 and not math.isnan(step := steps.pop()):
        return step
    if given:
        listed = ", ".join(f"{name} {text}" for name, text in given.items())
        raise SSPError(
            f"{where}: the FMUs' DefaultExperiment stepSize values differ or are invalid "
            f"({listed} s): give the communication step with --step"
        )
    raise SSPError(
        f"{where}: no communication step (no osp:FixedStepAlgorithm, oms:FixedStepMaster or "
        "FMU DefaultExperiment stepSize): give one with --step"
    )


def _read_stop_time(root: ET.Element, where: str, given: bool) -> float:
    """``ssd:DefaultExperiment stopTime`` (s); NaN when it is missing and ``given``
    (the caller's stop time is used)."""
    exp = root.find("ssd:DefaultExperiment", NS)
    start, stop = (None, None) if exp is None else (exp.get("startTime"), exp.get("stopTime"))
    try:
        start_f = float(start) if start is not None else 0.0
    except ValueError:
        start_f = math.nan
    if start_f != 0.0:
        raise SSPError(f"{where}: ssd:DefaultExperiment startTime = {start!r}: only 0 is supported")
    if stop is None:
        if given:
            return math.nan
        missing = "no ssd:DefaultExperiment" if exp is None else "no ssd:DefaultExperiment stopTime"
        raise SSPError(f"{where}: {missing}: give the end of the run with --stop-time")
    stop_f = _positive(stop)
    if math.isnan(stop_f):
        raise SSPError(
            f"{where}: ssd:DefaultExperiment stopTime = {stop!r} is invalid: expected a "
            "number > 0 (s)"
        )
    return stop_f


def load_ssp(
    path: str | Path, *, step: float | None = None, stop_time: float | None = None
) -> tuple[System, float, float]:
    """Read an SSP 1.0 or 2.0 into our master's :class:`~glider_cosim.master.System`.

    Parameters
    ----------
    path : path
        An ``.ssp`` archive (unpacked to a temporary folder, removed at exit), a
        ``.ssd`` file, or a folder holding ``SystemStructure.ssd``.
    step : float, optional
        The communication step (s), used instead of the SSP's (``--step``); needed when
        the SSP gives none.
    stop_time : float, optional
        The end of the run (s), used instead of ``ssd:DefaultExperiment stopTime``
        (``--stop-time``); needed when the SSP gives none.

    Returns
    -------
    (System, float, float)
        The system (FMU paths, parameter values, connections, unconnected Real inputs
        driven at their start or bound value, every output recorded), the communication
        step (s) and the stop time (s). The step is ``step`` if given, else the SSP's:
        ``osp:FixedStepAlgorithm baseStepSize`` (ours, libcosim's), OMSimulator's
        ``oms:FixedStepMaster stepSize``, or the FMUs' ``DefaultExperiment stepSize``
        when they agree. The stop time is ``stop_time`` if given, else
        ``ssd:DefaultExperiment stopTime``.

    Raises
    ------
    SSPError
        Missing or unreadable file or FMU, unknown component, connector or variable,
        connection that does not go from an output to an input of the same type,
        unsupported SSP feature or version, a step or stop time that is missing (the
        message names ``--step`` or ``--stop-time``) or not positive. Only model
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
        raise SSPError(f"{where}: the root element is not an SSP ssd:SystemStructureDescription")
    if root.get("version") not in SSD_VERSIONS:
        raise SSPError(
            f"{where}: SSD version {root.get('version')!r} is not supported: expected "
            + " or ".join(SSD_VERSIONS)
        )
    system = root.find("ssd:System", NS)
    if system is None:
        raise SSPError(f"{where}: no ssd:System element")
    if system.find("ssd:Elements/ssd:System", NS) is not None:
        raise SSPError(f"{where}: nested ssd:System elements (sub-systems) are not supported")
    if system.find("ssd:Elements/ssd:SignalDictionaryReference", NS) is not None:
        raise SSPError(f"{where}: ssd:SignalDictionaryReference is not supported")
    stop = _read_stop_time(root, where, stop_time is not None)

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
    h = float(step) if step is not None else _read_step(root, comps, where)
    stop = float(stop_time) if stop_time is not None else stop

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
    return system_, h, stop
