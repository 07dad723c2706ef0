"""An FMU's ``modelDescription.xml`` read with the standard library (issue 48).

:func:`parse_model_description` reads an FMI 2.0 or 3.0 model description into plain
objects with the attribute names of fmpy's ``read_model_description`` (``fmiVersion``,
``guid``, ``coSimulation.modelIdentifier``, ``modelVariables`` with ``name``,
``valueReference``, ``type``, ``causality``, ``variability``, ``initial``, ``start``,
``unit``, ``declaredType``, ``min``, ``max``; ``outputs`` and ``initialUnknowns`` with
``dependencies`` and ``dependenciesKind``; ``unitDefinitions``, ``typeDefinitions``,
``defaultExperiment``), the same values and the same defaults (``causality`` local, the
FMI 2 ``variability`` continuous, ``initial`` from causality and variability), so that a
run needs neither fmpy nor lxml nor attrs: importing them cost a run 30-40 ms.
``tests/integration/test_description.py`` holds the two readers against each other on
every FMU of the project.

It does not validate against the FMI schema as fmpy does: the master reads an FMU outside
the FMU cache with fmpy's checks as well (:func:`~glider_cosim.inputs.archives.read_fmu`).
What this reader needs and cannot find (no ``ModelVariables``, a variable without a value
reference or type, an index out of range, an undefined ``declaredType``, an illegal
causality and variability) is a :class:`ModelDescriptionError`.
"""

from __future__ import annotations

import copy
from typing import Any
from xml.etree import ElementTree as ET

__all__ = ["ModelDescription", "ModelDescriptionError", "ModelVariable", "parse_model_description"]


class ModelDescriptionError(ValueError):
    """A model description cannot be read: what is wrong, in one line."""


class _Record:
    """Attributes from keyword arguments over the class's defaults; a list default is
    a fresh list per object."""

    _defaults: dict[str, Any] = {}

    def __init__(self, **kw: Any):
        for k, v in self._defaults.items():
            setattr(self, k, list(v) if isinstance(v, list) else v)
        for k, v in kw.items():
            setattr(self, k, v)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({getattr(self, 'name', '')!r})"


class DefaultExperiment(_Record):
    """``startTime``, ``stopTime``, ``tolerance``, ``stepSize`` as written (str or None)."""

    _defaults = dict.fromkeys(("startTime", "stopTime", "tolerance", "stepSize"))


class CoSimulation(_Record):
    """The ``CoSimulation`` element's attributes (flags as bool)."""

    _defaults = {"modelIdentifier": None, "maxOutputDerivativeOrder": 0,
                 **dict.fromkeys(("needsExecutionTool", "canHandleVariableCommunicationStepSize",
                                  "canInterpolateInputs", "canRunAsynchronuously",
                                  "canBeInstantiatedOnlyOncePerProcess",
                                  "canNotUseMemoryManagementFunctions", "canGetAndSetFMUstate",
                                  "canSerializeFMUstate", "providesDirectionalDerivative",
                                  "hasEventMode", "providesIntermediateUpdate"),
                                 False)}  # fmt: skip


class BaseUnit(_Record):
    """SI exponents (int) and ``factor``, ``offset`` (float)."""

    _defaults = {**dict.fromkeys(("kg", "m", "s", "A", "K", "mol", "cd", "rad"), 0),
                 "factor": 1.0, "offset": 0.0}  # fmt: skip


class DisplayUnit(_Record):
    """``name``, ``factor`` and ``offset`` (float)."""

    _defaults = {"name": None, "factor": 1.0, "offset": 0.0}


class Unit(_Record):
    """``name``, ``baseUnit`` (or None) and ``displayUnits``."""

    _defaults = {"name": None, "baseUnit": None, "displayUnits": []}


class Item(_Record):
    """An enumeration item: ``name``, ``value``, ``description``."""

    _defaults = dict.fromkeys(("name", "value", "description"))


class SimpleType(_Record):
    """A type definition (``type`` is Real, Float64, ...; ``unit``, ``min``, ...)."""

    _defaults = {**dict.fromkeys(("name", "description", "type", "quantity", "unit",
                                  "displayUnit", "min", "max", "nominal", "unbounded")),
                 "relativeQuantity": False, "items": []}  # fmt: skip


class ModelVariable(_Record):
    """A variable: ``start``, ``min``, ``max`` and ``nominal`` as written (str or None)."""

    _defaults = {**dict.fromkeys(("name", "valueReference", "type", "description", "causality",
                                  "variability", "initial", "start", "declaredType", "quantity",
                                  "unit", "displayUnit", "relativeQuantity", "min", "max",
                                  "nominal", "derivative", "alias")),
                 "unbounded": False, "aliases": []}  # fmt: skip


class Unknown(_Record):
    """A model structure entry: ``variable``, ``dependencies`` (variables, or None when
    not declared) and ``dependenciesKind`` (str, or None)."""

    _defaults = {"index": 0, "variable": None, "dependencies": None, "dependenciesKind": None}


class ModelDescription(_Record):
    """The model description (``guid`` is FMI 3's ``instantiationToken``)."""

    _defaults = {**dict.fromkeys(("fmiVersion", "modelName", "guid", "description", "author",
                                  "version", "copyright", "license", "generationTool",
                                  "generationDateAndTime", "defaultExperiment", "coSimulation",
                                  "modelExchange")),
                 "variableNamingConvention": "flat", "numberOfContinuousStates": 0,
                 "numberOfEventIndicators": 0, "unitDefinitions": [], "typeDefinitions": [],
                 "modelVariables": [], "outputs": [], "derivatives": [],
                 "initialUnknowns": []}  # fmt: skip

    @property
    def instantiationToken(self) -> str | None:
        return self.guid


_FMI2_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")
_FMI3_TYPES = {"Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
               "Int64", "UInt64", "Boolean", "String", "Binary", "Enumeration",
               "Clock"}  # fmt: skip
_FLOATS = ("Real", "Float32", "Float64")
#: FMI's default ``initial`` by variability, then causality (None: no default: illegal)
_INITIAL = {
    "constant": {"output": "exact", "local": "exact"},
    "fixed": {"structuralParameter": "exact", "parameter": "exact",
              "calculatedParameter": "calculated", "local": "calculated"},
    "tunable": {"structuralParameter": "exact", "parameter": "exact",
                "calculatedParameter": "calculated", "local": "calculated"},
    "discrete": {"input": "exact", "output": "calculated", "local": "calculated"},
    "continuous": {"input": "exact", "output": "calculated", "local": "calculated",
                   "independent": None},
}  # fmt: skip
_PARAMETERS = {"parameter", "calculatedParameter", "structuralParameter"}
_TRUE = {"true", "1"}


def _flags(element: ET.Element, obj: _Record) -> None:
    """Copy ``element``'s attributes onto ``obj``, typed as the defaults are."""
    for name, text in element.attrib.items():
        default = obj._defaults.get(name, "")
        if isinstance(default, bool):
            setattr(obj, name, text in _TRUE)
        elif isinstance(default, int | float):
            setattr(obj, name, _number(type(default), text, f"{element.tag} {name}"))
        elif name in obj._defaults:
            setattr(obj, name, text)


def _number(kind: type, text: str, what: str) -> Any:
    try:
        return kind(text)
    except ValueError:
        raise ModelDescriptionError(f"{what} = {text!r} is not a number") from None


def _units(root: ET.Element) -> list[Unit]:
    units = []
    for u in root.findall("UnitDefinitions/Unit"):
        unit = Unit(name=u.get("name"))
        for b in u.findall("BaseUnit"):
            unit.baseUnit = BaseUnit()
            _flags(b, unit.baseUnit)
        for d in u.findall("DisplayUnit"):
            display = DisplayUnit(name=d.get("name"))
            _flags(d, display)
            unit.displayUnits.append(display)
        units.append(unit)
    return units


def _types(root: ET.Element, fmi3: bool) -> dict[str | None, SimpleType | None]:
    found: dict[str | None, SimpleType | None] = {None: None}
    for t in root.findall("TypeDefinitions/*"):
        if fmi3:
            if not t.tag.endswith("Type") or t.tag[:-4] not in _FMI3_TYPES - {"Clock"}:
                continue  # (fmpy reads no ClockType either)
            first, kind = t, t.tag[:-4]
        else:
            if t.tag != "SimpleType" or len(t) == 0:
                continue
            first = t[0]
            kind = first.tag
        st = SimpleType(name=t.get("name"), type=kind)
        for k, v in first.attrib.items():
            setattr(st, k, v)
        st.relativeQuantity = first.get("relativeQuantity") in _TRUE
        st.items = [Item(**i.attrib) for i in first.findall("Item")]
        found[st.name] = st
    return found


def _variable(el: ET.Element, fmi3: bool, types: dict) -> ModelVariable:
    name = el.get("name")
    vr = el.get("valueReference")
    if vr is None:
        raise ModelDescriptionError(f"variable {name!r} has no valueReference")
    v = ModelVariable(
        name=name, valueReference=_number(int, vr, f"variable {name!r} valueReference")
    )
    if fmi3:
        value = el
    else:
        value = next((c for c in el if c.tag in _FMI2_TYPES), None)
        if value is None:
            raise ModelDescriptionError(f"variable {name!r} has no type element (Real, ...)")
    v.type = value.tag
    if fmi3 and v.type not in _FMI3_TYPES:
        raise ModelDescriptionError(f"variable {name!r} has an unknown type {v.type!r}")
    v.description = el.get("description")
    v.causality = el.get("causality", "local")
    v.variability = el.get("variability")
    v.initial = el.get("initial")
    if el.tag in ("Binary", "String") and fmi3:
        start = el.find("Start")
        v.start = start.get("value") if start is not None else None
    else:
        v.start = value.get("start")
    if v.type in _FLOATS:
        v.unit, v.displayUnit = value.get("unit"), value.get("displayUnit")
        v.derivative, v.nominal = value.get("derivative"), value.get("nominal")
        v.unbounded = value.get("unbounded") in _TRUE
    if v.type in ("Real", "Enumeration") or v.type.startswith(("Float", "Int")):  # as fmpy
        v.quantity, v.min, v.max = value.get("quantity"), value.get("min"), value.get("max")
    declared = value.get("declaredType")
    if declared not in types:
        raise ModelDescriptionError(f"variable {name!r} has declaredType {declared!r}, not defined")
    v.declaredType = types[declared]
    if v.variability is None:
        if not fmi3:
            v.variability = "continuous"
        elif v.causality in _PARAMETERS:
            v.variability = "fixed"
        else:
            v.variability = "continuous" if v.type in _FLOATS else "discrete"
    if v.initial is None:
        try:
            v.initial = _INITIAL[v.variability][v.causality]
        except KeyError:
            raise ModelDescriptionError(
                f"variable {name!r} has an illegal combination of causality={v.causality!r} "
                f"and variability={v.variability!r}"
            ) from None
    if fmi3:
        for a in el.findall("Alias"):
            v.aliases.append(_Record(**{k: a.get(k) for k in ("name", "description",
                                                              "displayUnit")}))  # fmt: skip
    return v


def _structure(root: ET.Element, md: ModelDescription, fmi3: bool) -> None:
    variables = md.modelVariables
    by_vr = {v.valueReference: v for v in variables}

    def find(ref: str, what: str) -> ModelVariable:
        n = _number(int, ref, what)
        if fmi3:
            if n not in by_vr:
                raise ModelDescriptionError(f"{what} names value reference {n}: no variable has it")
            return by_vr[n]
        if not 1 <= n <= len(variables):
            raise ModelDescriptionError(f"{what} names variable index {n}: out of range")
        return variables[n - 1]

    kinds = ("Output", "ContinuousStateDerivative", "InitialUnknown")
    if not fmi3:
        kinds = ("Outputs/Unknown", "Derivatives/Unknown", "InitialUnknowns/Unknown")
    for target, path in zip((md.outputs, md.derivatives, md.initialUnknowns), kinds, strict=True):
        for u in root.findall(f"ModelStructure/{path}"):
            what = f"ModelStructure/{path}"
            key = u.get("valueReference" if fmi3 else "index")
            if key is None:
                raise ModelDescriptionError(
                    f"{what} has no {'valueReference' if fmi3 else 'index'}"
                )
            unknown = Unknown(variable=find(key, what))
            deps = u.get("dependencies")
            if deps is not None:
                unknown.dependencies = [find(d, f"{what} dependencies") for d in deps.split()]
            kind = u.get("dependenciesKind")
            if kind is not None:
                unknown.dependenciesKind = kind.split()
            target.append(unknown)
    if not fmi3:
        md.numberOfContinuousStates = len(md.derivatives)
    for v in variables:
        if v.derivative is not None:
            v.derivative = find(v.derivative, f"variable {v.name!r} derivative")


def parse_model_description(data: bytes | str) -> ModelDescription:
    """The model description in ``data`` (the bytes of ``modelDescription.xml``).

    Raises
    ------
    ModelDescriptionError
        Not well-formed XML, not an FMI 2.0 or 3.x model description, or something the
        reader needs is missing or wrong (see the module's docstring).
    """
    try:
        root = ET.fromstring(data)
    except ET.ParseError as err:
        raise ModelDescriptionError(f"not well-formed XML ({err})") from None
    if root.tag != "fmiModelDescription":
        raise ModelDescriptionError(
            f"the root element is <{root.tag}>: expected <fmiModelDescription>"
        )
    version = root.get("fmiVersion") or ""
    fmi3 = version.startswith("3.")
    if version != "2.0" and not fmi3:
        raise ModelDescriptionError(f"fmiVersion {version!r} is unsupported: expected 2.0 or 3.x")
    md = ModelDescription()
    for k in ("fmiVersion", "modelName", "description", "author", "version", "copyright",
              "license", "generationTool", "generationDateAndTime",
              "variableNamingConvention"):  # fmt: skip
        if k in root.attrib:
            setattr(md, k, root.get(k))
    md.guid = root.get("instantiationToken" if fmi3 else "guid")
    if root.get("numberOfEventIndicators") is not None:
        md.numberOfEventIndicators = _number(int, root.get("numberOfEventIndicators"),
                                             "numberOfEventIndicators")  # fmt: skip
    for d in root.findall("DefaultExperiment"):
        md.defaultExperiment = DefaultExperiment(
            **{k: d.get(k) for k in DefaultExperiment._defaults}
        )
    for cs in root.findall("CoSimulation"):
        md.coSimulation = CoSimulation()
        _flags(cs, md.coSimulation)
        if fmi3:
            md.coSimulation.canGetAndSetFMUstate = cs.get("canGetAndSetFMUState") in _TRUE
            md.coSimulation.canSerializeFMUstate = cs.get("canSerializeFMUState") in _TRUE
    for me in root.findall("ModelExchange"):
        md.modelExchange = _Record(modelIdentifier=me.get("modelIdentifier"))
    md.unitDefinitions = _units(root)
    types = _types(root, fmi3)
    md.typeDefinitions = [t for t in types.values() if t is not None]
    variables = root.find("ModelVariables")
    if variables is None:
        raise ModelDescriptionError("there is no ModelVariables element")
    md.modelVariables = [
        _variable(el, fmi3, types) for el in variables if el.get("name") is not None
    ]
    _structure(root, md, fmi3)
    if fmi3:  # an alias is a variable of its own name, as fmpy lists them
        for v in list(md.modelVariables):
            for a in v.aliases:
                twin = copy.copy(v)
                twin.name, twin.alias, twin.aliases = a.name, v, []
                twin.description = a.description or v.description
                twin.displayUnit = a.displayUnit or v.displayUnit
                md.modelVariables.append(twin)
    return md
