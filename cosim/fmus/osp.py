"""OSP-IS model descriptions (``<ModelIdentifier>_OspModelDescription.xml``) of our FMUs.

The Open Simulation Platform's interface specification (OSP-IS 1.0.1, schema
``OspModelDescription-1.0.1.xsd``) adds to an FMU's model description unit definitions
with SI exponents and typed *variable groups* (``Force``, ``Torque``,
``LinearVelocity``, ``AngularDisplacement``, ...; up to three ``Variable`` components
each, optionally with an ``axis``), so that tools connect quantities, not scalars.

Where the file goes: OSP's tools look for ``<name>_OspModelDescription.xml`` *beside the
FMU file*, then beside the ``OspSystemStructure.xml`` (libcosim's ``osp_config_parser``,
osp-validator's ``DefaultOspModelDescriptionLocator``); neither reads it from inside the
FMU. So every build writes it beside the ``.fmu`` (:func:`write_beside`), and the FMU
carries a copy in ``extra/com.opensimulationplatform/`` (FMI's folder for layered
standards' files, in reverse-domain notation) so that it travels with the FMU; an SSP
export puts it beside the FMU in ``resources/``.

Everything is generated from the FMU's ``modelDescription.xml`` (FMI 2 or FMI 3): its
units, and one group per input or output whose unit is an OSP quantity, except the
components :data:`VECTOR_GROUPS` joins into one group (the plant's disturbance force
``F_x``, ``F_z``; its position ``x``, ``z``). Parameters are set, not connected, and get
no group.
"""

from __future__ import annotations

import hashlib
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from .files import replacing

#: namespace of OSP-IS 1.0.1 (1.0.0 plus the ``axis`` attribute of ``Variable``)
NS = "https://open-simulation-platform.com/OspModelDescription/1.0.1"
SUFFIX = "_OspModelDescription.xml"
#: where the FMU carries its copy
EXTRA_DIR = "extra/com.opensimulationplatform"
_EXPONENTS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")

#: OSP-IS group type of a quantity, by SI exponents (kg, m, s, rad; the others zero)
QUANTITIES: dict[tuple[int, int, int, int], str] = {
    (1, 1, -2, 0): "Force",
    (1, 2, -2, 0): "Torque",
    (0, 1, -1, 0): "LinearVelocity",
    (0, 0, -1, 1): "AngularVelocity",
    (0, 1, 0, 0): "LinearDisplacement",
    (0, 0, 0, 1): "AngularDisplacement",
    (0, 1, -2, 0): "LinearAcceleration",
    (0, 0, -2, 1): "AngularAcceleration",
}
#: the order OSP-IS's ``VariableGroupsType`` (an xs:sequence) requires
GROUP_ORDER = (
    "Generic", "Force", "Torque", "Voltage", "Pressure", "LinearVelocity",
    "AngularVelocity", "Current", "VolumeFlowRate", "LinearDisplacement",
    "AngularDisplacement", "Charge", "Volume", "LinearAcceleration", "AngularAcceleration",
)  # fmt: skip
#: groups of several components (or a named axis): name -> (variable, axis) pairs. A
#: group is written when the FMU has all its variables, of one causality and quantity.
VECTOR_GROUPS: dict[str, tuple[tuple[str, str], ...]] = {
    "disturbance_force": (("F_x", "x"), ("F_z", "z")),
    "disturbance_moment": (("M_y", "y"),),
    "position": (("x", "x"), ("z", "z")),
}


class _Var:
    def __init__(self, name: str, causality: str, unit: str | None):
        self.name, self.causality, self.unit = name, causality, unit


def _parse(md_xml: bytes) -> tuple[ET.Element, list[_Var], dict[str, ET.Element]]:
    """Root, variables (name, causality, unit) and units of an FMI 2 or 3 description."""
    root = ET.fromstring(md_xml)
    declared = {}  # declaredType -> unit
    for t in root.iterfind("TypeDefinitions/*"):
        inner = t.find("Real") if t.tag == "SimpleType" else t  # FMI 2: SimpleType/Real
        if inner is not None and inner.get("unit"):
            declared[t.get("name")] = inner.get("unit")
    variables = []
    for v in root.find("ModelVariables"):
        if v.tag == "ScalarVariable":  # FMI 2
            typed = next(iter(v), None)
            if typed is None or typed.tag != "Real":
                continue
        else:  # FMI 3: Float64, Float32, ...
            if not v.tag.startswith("Float"):
                continue
            typed = v
        unit = typed.get("unit") or declared.get(typed.get("declaredType"))
        variables.append(_Var(v.get("name"), v.get("causality", "local"), unit))
    units = {u.get("name"): u for u in root.iterfind("UnitDefinitions/Unit")}
    return root, variables, units


def _exponents(unit: ET.Element | None) -> dict[str, int]:
    base = unit.find("BaseUnit") if unit is not None else None
    return {e: int(base.get(e, "0")) if base is not None else 0 for e in _EXPONENTS}


def _quantity(unit: ET.Element | None) -> str | None:
    if unit is None or unit.find("BaseUnit") is None:
        return None
    ex = _exponents(unit)
    base = unit.find("BaseUnit")
    if ex["A"] or ex["K"] or ex["mol"] or ex["cd"]:
        return None
    if float(base.get("factor", "1")) != 1.0 or float(base.get("offset", "0")) != 0.0:
        return None
    return QUANTITIES.get((ex["kg"], ex["m"], ex["s"], ex["rad"]))


def groups(md_xml: bytes) -> list[tuple[str, str, list[tuple[str, str | None, str | None]]]]:
    """The variable groups of a model description: (type, name, [(variable, unit, axis)]),
    in the order OSP-IS requires."""
    _, variables, units = _parse(md_xml)
    by_name = {v.name: v for v in variables}
    found = []
    taken: set[str] = set()
    for gname, comps in VECTOR_GROUPS.items():
        vs = [by_name.get(n) for n, _ in comps]
        if any(v is None or v.causality not in ("input", "output") for v in vs):
            continue
        kinds = {(v.causality, _quantity(units.get(v.unit))) for v in vs}
        if len(kinds) != 1 or next(iter(kinds))[1] is None:
            continue
        kind = next(iter(kinds))[1]
        found.append((kind, gname, [(v.name, v.unit, ax) for v, (_, ax) in zip(vs, comps)]))
        taken.update(v.name for v in vs)
    for v in variables:
        if v.name in taken or v.causality not in ("input", "output"):
            continue
        kind = _quantity(units.get(v.unit))
        if kind is not None:
            found.append((kind, v.name, [(v.name, v.unit, None)]))
    return sorted(found, key=lambda g: GROUP_ORDER.index(g[0]))


def generate(md_xml: bytes) -> bytes:
    """The OSP-IS model description of an FMU, from its ``modelDescription.xml``."""
    _, variables, units = _parse(md_xml)
    used = sorted({v.unit for v in variables if v.unit in units})
    ET.register_namespace("", NS)
    root = ET.Element(f"{{{NS}}}OspModelDescription", {"version": "1.0"})
    defs = ET.SubElement(root, f"{{{NS}}}UnitDefinitions")
    for name in used:
        unit = units[name]
        u = ET.SubElement(defs, f"{{{NS}}}Unit", {"name": name})
        base = unit.find("BaseUnit")
        attrs = {e: str(x) for e, x in _exponents(unit).items()}
        attrs["factor"] = repr(float(base.get("factor", "1"))) if base is not None else "1.0"
        attrs["offset"] = repr(float(base.get("offset", "0"))) if base is not None else "0.0"
        ET.SubElement(u, f"{{{NS}}}BaseUnit", attrs)
        for d in unit.iterfind("DisplayUnit"):
            da = {k: d.get(k) for k in ("name", "factor", "offset") if d.get(k) is not None}
            ET.SubElement(u, f"{{{NS}}}DisplayUnit", da)
    vgroups = ET.SubElement(root, f"{{{NS}}}VariableGroups")
    for kind, gname, comps in groups(md_xml):
        g = ET.SubElement(vgroups, f"{{{NS}}}{kind}", {"name": gname})
        for vname, unit, axis in comps:
            attrs = {"ref": vname}
            if unit:
                attrs["unit"] = unit
            if axis:
                attrs["axis"] = axis
            ET.SubElement(g, f"{{{NS}}}Variable", attrs)
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def model_identifier(md_xml: bytes) -> str:
    """The co-simulation model identifier (the model name if there is none)."""
    root = ET.fromstring(md_xml)
    cs = root.find("CoSimulation")
    return cs.get("modelIdentifier") if cs is not None else root.get("modelName")


def file_name(md_xml: bytes) -> str:
    """``<ModelIdentifier>_OspModelDescription.xml``."""
    return model_identifier(md_xml) + SUFFIX


def extra_path(md_xml: bytes) -> str:
    """Where the FMU carries its copy."""
    return f"{EXTRA_DIR}/{file_name(md_xml)}"


def add_to_fmu(fmu: Path) -> None:
    """Add the generated file to ``fmu`` (in :data:`EXTRA_DIR`), from its own model
    description; the FMU must not carry one yet."""
    with zipfile.ZipFile(fmu, "a", zipfile.ZIP_DEFLATED) as z:
        md = z.read("modelDescription.xml")
        z.writestr(extra_path(md), generate(md))


def carried(fmu: Path) -> tuple[str, bytes | None]:
    """(file name, content or None) of the OSP-IS description ``fmu`` carries."""
    with zipfile.ZipFile(fmu) as z:
        name = file_name(z.read("modelDescription.xml"))
        try:
            return name, z.read(f"{EXTRA_DIR}/{name}")
        except KeyError:
            return name, None


def read_from_fmu(fmu: Path) -> tuple[str, bytes] | None:
    """(file name, content) of the OSP-IS description ``fmu`` carries or has beside it;
    None if neither (or ``fmu`` is unreadable)."""
    try:
        name, content = carried(fmu)
    except (OSError, KeyError, zipfile.BadZipFile, ET.ParseError):
        return None
    if content is not None:
        return name, content
    beside = fmu.with_name(name)
    return (name, beside.read_bytes()) if beside.is_file() else None


def write_beside(fmu: Path) -> Path:
    """Write ``<ModelIdentifier>_OspModelDescription.xml`` beside ``fmu`` (the copy it
    carries, else generated from its model description); return its path."""
    name, content = carried(fmu)
    if content is None:
        with zipfile.ZipFile(fmu) as z:
            content = generate(z.read("modelDescription.xml"))
    target = fmu.with_name(name)
    if target.is_file() and target.read_bytes() == content:
        return target
    with replacing(target) as part:  # a name of its own: builds may run at once
        part.write_bytes(content)
    return target


def fingerprint() -> str:
    """Hash of this generator, part of the FMUs' source hashes (a change rebuilds them)."""
    return hashlib.sha256(Path(__file__).read_bytes()).hexdigest()
