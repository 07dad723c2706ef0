"""The FMI 3.0 model description of one of our FMUs, written from its FMI 2.0 one."""

from __future__ import annotations

from xml.etree import ElementTree as ET

#: FMI 2 variable types -> the FMI 3 ones (the master reads them the other way)
FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "String": "String"}


_COSIM_FLAGS = {
    "needsExecutionTool": "false",
    "canBeInstantiatedOnlyOncePerProcess": "false",
    "canGetAndSetFMUState": "true",
    "canSerializeFMUState": "true",
    "canHandleVariableCommunicationStepSize": "true",
    "hasEventMode": "false",
    "providesIntermediateUpdate": "false",
    "canReturnEarlyAfterIntermediateUpdate": "false",
    "providesEvaluateDiscreteStates": "false",
    "providesDirectionalDerivatives": "false",
    "providesAdjointDerivatives": "false",
}


def fmi3_model_description(md2: bytes, needs_execution_tool: bool = False) -> bytes:
    """An FMI 2.0 co-simulation model description of ours, written as FMI 3.0."""
    src = ET.fromstring(md2)
    root = ET.Element("fmiModelDescription", fmiVersion="3.0")
    for key in ("modelName", "description", "author", "version", "license", "generationTool",
                "generationDateAndTime", "variableNamingConvention"):  # fmt: skip
        if src.get(key):
            root.set(key, src.get(key))
    root.set("instantiationToken", src.get("guid", ""))
    cs2 = src.find("CoSimulation")
    cs = ET.SubElement(root, "CoSimulation", modelIdentifier=cs2.get("modelIdentifier"))
    for key, value in _COSIM_FLAGS.items():
        cs.set(key, value)
    if cs2.get("providesDirectionalDerivative") == "true":
        cs.set("providesDirectionalDerivatives", "true")
    if needs_execution_tool:
        cs.set("needsExecutionTool", "true")
    units = src.find("UnitDefinitions")
    if units is not None:
        root.append(units)
    cats = src.find("LogCategories")
    if cats is not None:
        out = ET.SubElement(root, "LogCategories")
        for c in cats:
            ET.SubElement(out, "Category", {k: v for k, v in c.attrib.items()})
    exp = src.find("DefaultExperiment")
    if exp is not None:
        root.append(exp)
    variables = ET.SubElement(root, "ModelVariables")
    vr_of_index: dict[int, str] = {}
    for i, sv in enumerate(src.find("ModelVariables"), start=1):
        typed = sv[0]
        attrs = {"name": sv.get("name"), "valueReference": sv.get("valueReference")}
        vr_of_index[i] = sv.get("valueReference")
        for key in ("description", "causality", "variability", "initial"):
            if sv.get(key):
                attrs[key] = sv.get(key)
        attrs.update(typed.attrib)
        if attrs.get("causality") == "parameter" and "start" in attrs:
            attrs.setdefault("initial", "exact")
        if typed.tag == "Boolean" and "start" in attrs:
            attrs["start"] = "true" if attrs["start"] in ("true", "1") else "false"
        ET.SubElement(variables, FMI3_TYPES[typed.tag], attrs)
    for v in variables:  # a state derivative names its state by value reference
        if v.get("derivative"):
            v.set("derivative", vr_of_index[int(v.get("derivative"))])
    # FMI 3 wants its independent variable declared: time, after the others' references
    next_vr = max((int(v) for v in vr_of_index.values()), default=-1) + 1
    ET.SubElement(variables, "Float64", name="time", valueReference=str(next_vr),
                  causality="independent", variability="continuous",
                  description="simulation time [s]", unit="s")  # fmt: skip
    structure = ET.SubElement(root, "ModelStructure")
    s2 = src.find("ModelStructure")
    for tag, out_tag in (("Outputs", "Output"), ("Derivatives", "ContinuousStateDerivative"),
                         ("InitialUnknowns", "InitialUnknown")):  # fmt: skip
        group = s2.find(tag)
        for u in group if group is not None else ():
            attrs = {"valueReference": vr_of_index[int(u.get("index"))]}
            if u.get("dependencies") is not None:  # as value references (FMI 3)
                deps = u.get("dependencies").split()
                attrs["dependencies"] = " ".join(vr_of_index[int(d)] for d in deps)
                if u.get("dependenciesKind") is not None:
                    attrs["dependenciesKind"] = u.get("dependenciesKind")
            ET.SubElement(structure, out_tag, attrs)
    ET.indent(root, "\t")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")
