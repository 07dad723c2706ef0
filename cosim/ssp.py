"""SSP 1.0 export and import of the glider system (``glider-cosim export-ssp``,
``glider-cosim run FILE.ssp``), and a libcosim run of an SSP for comparison.

The archive holds ``SystemStructure.ssd`` (components with their connectors, the
connections, inline parameter values, the default experiment with the 0.02 s step as an
``osp:FixedStepAlgorithm`` annotation, which libcosim reads) and the FMUs under
``resources/``.
"""

from __future__ import annotations

import math
import shutil
import tempfile
import zipfile
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from fmpy import read_model_description

from .master import System
from .runner import FMU_NAMES, default_connections
from .scenario import Scenario, load_scenario

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
}
for _p, _u in NS.items():
    ET.register_namespace(_p, _u)
_TYPES = {"Real": "Real", "Integer": "Integer", "Boolean": "Boolean"}


class SSPError(ValueError):
    """A malformed or incompatible SSP; the message names the element."""


def _q(prefix: str, tag: str) -> str:
    return f"{{{NS[prefix]}}}{tag}"


def export_ssp(
    out_path: str | Path, scenario: Scenario | str | None = None, fmu_dir: str | Path = "fmus"
) -> Path:
    """Write the scenario's system as an SSP 1.0 archive (``.ssp``) and return its path."""
    from .build import build_all

    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if scenario.events or scenario.disturbances or scenario.fmus:
        raise SSPError(
            f"{scenario.source}: events, disturbances and swapped FMUs have no SSP 1.0 "
            "equivalent; export a scenario without them"
        )
    fmus = build_all(fmu_dir, only_stale=True)
    insts = {i: n for i, n in FMU_NAMES.items() if scenario.observer or i != "observer"}
    conns = default_connections(scenario.feedback, scenario.observer)
    root = ET.Element(_q("ssd", "SystemStructureDescription"),
                      {"version": "1.0", "name": f"glider-cosim-{scenario.name}"})  # fmt: skip
    system = ET.SubElement(root, _q("ssd", "System"), {"name": "glider"})
    elements = ET.SubElement(system, _q("ssd", "Elements"))
    for inst, name in insts.items():
        md = read_model_description(str(fmus[name]))
        comp = ET.SubElement(elements, _q("ssd", "Component"), {
            "name": inst, "source": f"resources/{name}.fmu",
            "type": "application/x-fmu-sharedlibrary"})  # fmt: skip
        cons = ET.SubElement(comp, _q("ssd", "Connectors"))
        for v in md.modelVariables:
            if v.causality in ("input", "output") and v.type in _TYPES:
                c = ET.SubElement(cons, _q("ssd", "Connector"),
                                  {"name": v.name, "kind": v.causality})  # fmt: skip
                ET.SubElement(c, _q("ssc", v.type))
        params = scenario.parameters.get(inst, {})
        if params:
            types = {v.name: v.type for v in md.modelVariables}
            pb = ET.SubElement(ET.SubElement(comp, _q("ssd", "ParameterBindings")),
                               _q("ssd", "ParameterBinding"))  # fmt: skip
            pv = ET.SubElement(pb, _q("ssd", "ParameterValues"))
            ps = ET.SubElement(pv, _q("ssv", "ParameterSet"),
                               {"version": "1.0", "name": f"{inst}-parameters"})  # fmt: skip
            plist = ET.SubElement(ps, _q("ssv", "Parameters"))
            for k, val in params.items():
                t = types.get(k, "Real")
                p = ET.SubElement(plist, _q("ssv", "Parameter"), {"name": k})
                text = repr(float(val)) if t == "Real" else (
                    str(bool(val)).lower() if t == "Boolean" else str(int(val)))  # fmt: skip
                ET.SubElement(p, _q("ssv", t), {"value": text})
    cn = ET.SubElement(system, _q("ssd", "Connections"))
    for src, dst in conns:
        (se, sc), (de, dc) = src.split(".", 1), dst.split(".", 1)
        attrs = {"startElement": se, "startConnector": sc, "endElement": de, "endConnector": dc}
        ET.SubElement(cn, _q("ssd", "Connection"), attrs)
    de = ET.SubElement(root, _q("ssd", "DefaultExperiment"),
                       {"startTime": "0.0", "stopTime": repr(scenario.stop_time)})  # fmt: skip
    ann = ET.SubElement(ET.SubElement(de, _q("ssd", "Annotations")), _q("ssc", "Annotation"),
                        {"type": "com.opensimulationplatform"})  # fmt: skip
    alg = ET.SubElement(ann, _q("osp", "Algorithm"))
    ET.SubElement(alg, _q("osp", "FixedStepAlgorithm"), {"baseStepSize": repr(scenario.step)})
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    ET.indent(root)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("SystemStructure.ssd", ET.tostring(root, xml_declaration=True,
                                                      encoding="UTF-8"))  # fmt: skip
        for name in insts.values():
            z.write(fmus[name], f"resources/{name}.fmu")
    return out


def _unpack(path: Path) -> tuple[Path, Path]:
    """(folder, ssd file) of an .ssp archive, an .ssd file or a folder."""
    if path.is_dir():
        return path, path / "SystemStructure.ssd"
    if path.suffix == ".ssd":
        return path.parent, path
    try:
        tmp = Path(tempfile.mkdtemp(prefix="glider_ssp_"))
        with zipfile.ZipFile(path) as z:
            z.extractall(tmp)
    except (OSError, zipfile.BadZipFile) as err:
        raise SSPError(f"{path}: not a readable SSP archive ({err})") from None
    return tmp, tmp / "SystemStructure.ssd"


def load_ssp(path: str | Path) -> tuple[System, float, float]:
    """Read an SSP into our master's :class:`System`; returns (system, step, stop_time).

    Every component, connector, connection and parameter is checked against the FMUs'
    model descriptions before any FMU is instantiated.
    """
    path = Path(path)
    if not path.exists():
        raise SSPError(f"{path}: SSP file does not exist")
    folder, ssd = _unpack(path)
    if not ssd.exists():
        raise SSPError(f"{path}: SystemStructure.ssd is missing")
    try:
        root = ET.parse(ssd).getroot()
    except ET.ParseError as err:
        raise SSPError(f"{path}: SystemStructure.ssd is not valid XML ({err})") from None
    system = root.find("ssd:System", NS)
    if system is None:
        raise SSPError(f"{path}: no ssd:System element")
    fmus: dict[str, Path] = {}
    variables: dict[str, dict[str, Any]] = {}
    parameters: dict[str, dict[str, Any]] = {}
    for comp in system.iterfind("ssd:Elements/ssd:Component", NS):
        name, source = comp.get("name"), comp.get("source")
        if not name or not source:
            raise SSPError(f"{path}: a ssd:Component lacks its name or source attribute")
        fmu = folder / source
        if not fmu.exists():
            raise SSPError(f"{path}: component '{name}': FMU '{source}' is missing")
        fmus[name] = fmu
        md = read_model_description(str(fmu))
        variables[name] = {v.name: v for v in md.modelVariables}
        for c in comp.iterfind("ssd:Connectors/ssd:Connector", NS):
            v = variables[name].get(c.get("name"))
            if v is None:
                raise SSPError(f"{path}: component '{name}': connector '{c.get('name')}' is not "
                               f"a variable of {source}")  # fmt: skip
            if c.get("kind") in ("input", "output") and v.causality != c.get("kind"):
                raise SSPError(f"{path}: component '{name}': connector '{v.name}' is declared "
                               f"{c.get('kind')} but is {v.causality} in {source}")  # fmt: skip
        for p in comp.iterfind(".//ssv:Parameter", NS):
            pname = p.get("name")
            if pname not in variables[name]:
                raise SSPError(f"{path}: component '{name}': parameter '{pname}' is not a "
                               f"variable of {source}")  # fmt: skip
            val = next(iter(p), None)
            if val is None or val.get("value") is None:
                raise SSPError(f"{path}: component '{name}': parameter '{pname}' has no value")
            tag = val.tag.split("}")[-1]
            text = val.get("value")
            try:
                if tag == "Real":
                    value: Any = float(text)
                else:
                    value = text.lower() == "true" if tag == "Boolean" else int(text)
            except ValueError:
                raise SSPError(f"{path}: component '{name}': parameter '{pname}' value "
                               f"{text!r} is not a {tag}") from None  # fmt: skip
            parameters.setdefault(name, {})[pname] = value
    if not fmus:
        raise SSPError(f"{path}: the system has no components")
    conns = []
    for c in system.iterfind("ssd:Connections/ssd:Connection", NS):
        se, sc = c.get("startElement"), c.get("startConnector")
        de, dc = c.get("endElement"), c.get("endConnector")
        for el, con in ((se, sc), (de, dc)):
            if el not in fmus:
                raise SSPError(f"{path}: connection {se}.{sc} -> {de}.{dc}: unknown element "
                               f"'{el}'")  # fmt: skip
            if con not in variables[el]:
                raise SSPError(f"{path}: connection {se}.{sc} -> {de}.{dc}: '{el}' has no "
                               f"variable '{con}'")  # fmt: skip
        conns.append((f"{se}.{sc}", f"{de}.{dc}"))
    step = None
    for alg in root.iter(_q("osp", "FixedStepAlgorithm")):
        step = alg.get("baseStepSize")
    exp = root.find("ssd:DefaultExperiment", NS)
    stop = exp.get("stopTime") if exp is not None else None
    try:
        step_f = float(step) if step is not None else math.nan
        stop_f = float(stop) if stop is not None else math.nan
    except ValueError:
        raise SSPError(
            f"{path}: osp:FixedStepAlgorithm baseStepSize {step!r} or DefaultExperiment "
            f"stopTime {stop!r} is not a number"
        ) from None
    if not (math.isfinite(step_f) and step_f > 0):
        raise SSPError(f"{path}: osp:FixedStepAlgorithm baseStepSize = {step!r}: expected a "
                       "number > 0 (the communication step)")  # fmt: skip
    if not (math.isfinite(stop_f) and stop_f > 0):
        raise SSPError(f"{path}: ssd:DefaultExperiment stopTime = {stop!r}: expected > 0")
    connected = {d for _, d in conns}
    driven = {}
    for inst, vs in variables.items():
        for v in vs.values():
            ref = f"{inst}.{v.name}"
            if v.causality == "input" and ref not in connected and v.type == "Real":
                driven[ref] = float(v.start or 0.0)
    return (System(fmus=fmus, connections=conns, parameters=parameters, driven=driven),
            step_f, stop_f)  # fmt: skip


def simulate_libcosim(
    path: str | Path, variables: list[str], stop_time: float
) -> list[list[float]]:
    """Run an SSP in libcosim (libcosimpy) and return rows ``[t, *variables]`` at every
    step, the initial point included. Run it in a subprocess: an FMU exception during
    libcosim's initialisation aborts the process."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)

    ex = CosimExecution.from_ssp_file(str(path))
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    refs = []
    for var in variables:
        inst, name = var.split(".", 1)
        idx = ex.slave_index_from_instance_name(inst)
        vr = next(v.reference for v in ex.slave_variables(idx) if v.name.decode() == name)
        refs.append((idx, vr))
    _, step, _ = load_ssp(path)
    n = round(stop_time / step)
    rows = []
    for k in range(n + 1):
        if k:
            ex.step()
        rows.append([k * step, *(obs.last_real_values(i, [vr])[0] for i, vr in refs)])
    return rows


def cleanup(system: System) -> None:
    """Remove the folder an SSP archive was unpacked to."""
    folders = {Path(p).parent.parent for p in system.fmus.values()}
    for f in folders:
        if f.name.startswith("glider_ssp_"):
            shutil.rmtree(f, ignore_errors=True)
