"""The system as an SSP archive (``glider-cosim export-ssp``): SSP 1.0 for FMI 2.0 FMUs,
SSP 2.0 (FMI 3's types) when an FMU is FMI 3.0."""

from __future__ import annotations

import re
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING
from xml.etree import ElementTree as ET

from ..fmus import osp
from ..inputs.ssp_files import SSD_NAME, SSPError

if TYPE_CHECKING:
    from ..scenarios.scenario import Scenario
from .ssp_common import (
    FMU_MIME,
    OSP_ANNOTATION_TYPE,
    OSP_MD_ANNOTATION_TYPE,
    OSP_MD_NS,
    SSD_VERSIONS,
    VALUE_TYPES,
    as_ssp1_type,
    format_value,
    qname,
)


def ssd_name(scenario_name: str) -> str:
    """The SSD's ``name``: a plain identifier (``glider_cosim_<scenario>``, every other
    character an underscore), which every importer takes (OMSimulator's refuses others)."""
    return re.sub(r"[^A-Za-z0-9_]", "_", f"glider_cosim_{scenario_name}")


def export_ssp(
    out_path: str | Path,
    scenario: Scenario | str | Path | None = None,
    fmu_dir: str | Path | None = None,
    *,
    ssp_version: str | None = None,
) -> Path:
    """Write a scenario's system as an SSP archive: SSP 1.0 when every FMU is FMI 2.0,
    SSP 2.0 (``version="2.0"``, connectors and values typed ``Float64``/``Int32`` as
    FMI 3's) when one is FMI 3.0.

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
    ssp_version : {"1.0", "2.0"}, optional
        The SSP version to write; default 2.0 when an FMU is FMI 3.0, else 1.0. SSP 1.0
        of FMI 3.0 FMUs types their Float64/Int32 variables as SSP 1.0's Real/Integer
        (for importers that read only SSP 1.0, such as Ecos 0.7).

    Returns
    -------
    Path
        ``out_path``.

    Raises
    ------
    SSPError
        The scenario cannot be expressed in SSP, names a variable the FMUs lack, or
        ``ssp_version`` is not 1.0 or 2.0.
    """
    from fmpy import read_model_description

    from ..components import component
    from ..fmus.folders import build_all, fmu_folder
    from ..scenarios.sampling import has_our_observer, with_sampling
    from ..scenarios.scenario import Scenario, load_scenario
    from ..scenarios.system import scenario_connections, swapped

    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if sc.events or sc.disturbances:
        key = "event" if sc.events else "disturbance"
        raise SSPError(
            f"{sc.source}: key '{key}': events and disturbances have no SSP 1.0 equivalent; "
            "export a scenario without them"
        )
    insts = sc.instances()
    ours = set(insts) - set(sc.fmus)  # handed on: every platform's binary
    built = (
        build_all(fmu_folder(fmu_dir), only_stale=True, host_only=False, skip=swapped(sc))
        if ours
        else {}
    )
    fmus: dict[str, Path] = {}
    for inst in insts:
        fmus[inst] = Path(sc.fmus[inst]) if inst in sc.fmus else built[component(inst).model]
    resources = {inst: f"resources/{fmu.name}" for inst, fmu in fmus.items()}
    if len(set(resources.values())) != len(resources):
        raise SSPError(f"{sc.source}: key 'fmus': two instances use FMU files of the same name")
    conns = scenario_connections(sc)
    ospmd = {}  # inst -> (path in the archive, content): beside its FMU, as OSP looks
    for inst, fmu in fmus.items():
        found = osp.read_from_fmu(fmu)
        if found is not None:
            ospmd[inst] = (f"resources/{Path(resources[inst]).stem}{osp.SUFFIX}", found[1])

    mds = {inst: read_model_description(str(fmus[inst])) for inst in insts}
    fmi3 = {inst: str(md.fmiVersion).startswith("3") for inst, md in mds.items()}
    if ssp_version not in (None, *SSD_VERSIONS):
        raise SSPError(
            f"ssp_version {ssp_version!r} is invalid: expected " + " or ".join(SSD_VERSIONS)
        )
    version = ssp_version or ("2.0" if any(fmi3.values()) else "1.0")
    root = ET.Element(
        qname("ssd", "SystemStructureDescription"),
        {"version": version, "name": ssd_name(sc.name)},
    )
    system = ET.SubElement(root, qname("ssd", "System"), {"name": "glider"})
    elements = ET.SubElement(system, qname("ssd", "Elements"))
    comps = {}
    for inst in insts:
        md = mds[inst]
        variables = {v.name: v for v in md.modelVariables}
        # FMI 3's type names (SSP 2.0) for an FMI 3 FMU, SSP 1.0's (FMI 2's) otherwise
        as_tag = (lambda t: t) if fmi3[inst] and version == "2.0" else as_ssp1_type
        comp = comps[inst] = ET.SubElement(
            elements,
            qname("ssd", "Component"),
            {"name": inst, "source": resources[inst], "type": FMU_MIME},
        )
        connectors = ET.SubElement(comp, qname("ssd", "Connectors"))
        for v in md.modelVariables:
            if v.causality in ("input", "output") and as_ssp1_type(v.type) in VALUE_TYPES:
                c = ET.SubElement(
                    connectors, qname("ssd", "Connector"), {"name": v.name, "kind": v.causality}
                )
                ET.SubElement(c, qname("ssc", as_tag(v.type)))
        values = dict(
            with_sampling(sc.parameters, sc.step, sc.source, has_our_observer(sc)).get(inst, {})
        )
        for ref, value in sc.inputs.items():  # constant inputs: their start values
            if ref.startswith(f"{inst}."):
                values[ref.split(".", 1)[1]] = value
        if not values:
            continue
        bindings = ET.SubElement(comp, qname("ssd", "ParameterBindings"))
        binding = ET.SubElement(bindings, qname("ssd", "ParameterBinding"))
        pvalues = ET.SubElement(binding, qname("ssd", "ParameterValues"))
        pset = ET.SubElement(
            pvalues,
            qname("ssv", "ParameterSet"),
            {"version": version, "name": f"{inst}-parameters"},
        )
        params = ET.SubElement(pset, qname("ssv", "Parameters"))
        for name, value in values.items():
            v = variables.get(name)
            if v is None or v.causality not in ("parameter", "input"):
                raise SSPError(
                    f"{sc.source}: key '{inst}.{name}': {fmus[inst].name} has no parameter or "
                    f"input '{name}'"
                )
            if as_ssp1_type(v.type) not in VALUE_TYPES:
                raise SSPError(f"{sc.source}: key '{inst}.{name}': type {v.type} is not supported")
            p = ET.SubElement(params, qname("ssv", "Parameter"), {"name": name})
            ET.SubElement(p, qname("ssv", as_tag(v.type)), {"value": format_value(value, v.type)})
    for inst, (path, _) in ospmd.items():  # Annotations come last in an ssd:Component
        annotation = ET.SubElement(
            ET.SubElement(comps[inst], qname("ssd", "Annotations")),
            qname("ssc", "Annotation"),
            {"type": OSP_MD_ANNOTATION_TYPE},
        )
        ET.SubElement(annotation, f"{{{OSP_MD_NS}}}OspModelDescription", {"source": path})
    connections = ET.SubElement(system, qname("ssd", "Connections"))
    for src, dst in conns:
        (se, sc_), (de, dc) = src.split(".", 1), dst.split(".", 1)
        ET.SubElement(
            connections,
            qname("ssd", "Connection"),
            {"startElement": se, "startConnector": sc_, "endElement": de, "endConnector": dc},
        )
    experiment = ET.SubElement(
        root,
        qname("ssd", "DefaultExperiment"),
        {"startTime": "0.0", "stopTime": repr(float(sc.stop_time))},
    )
    annotation = ET.SubElement(
        ET.SubElement(experiment, qname("ssd", "Annotations")),
        qname("ssc", "Annotation"),
        {"type": OSP_ANNOTATION_TYPE},
    )
    ET.SubElement(
        ET.SubElement(annotation, qname("osp", "Algorithm")),
        qname("osp", "FixedStepAlgorithm"),
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
