"""Every attribute of a model description that glider-cosim reads, as plain values: the
same function applied to fmpy's ``read_model_description`` and to our
``glider_cosim.inputs.description`` reader must give equal results (issue 48)."""

from __future__ import annotations

from typing import Any

CO_SIMULATION = ("modelIdentifier", "needsExecutionTool", "canHandleVariableCommunicationStepSize",
                 "canInterpolateInputs", "canBeInstantiatedOnlyOncePerProcess",
                 "canNotUseMemoryManagementFunctions", "canGetAndSetFMUstate",
                 "canSerializeFMUstate", "providesDirectionalDerivative",
                 "maxOutputDerivativeOrder", "hasEventMode",
                 "providesIntermediateUpdate")  # fmt: skip
BASE_UNIT = ("kg", "m", "s", "A", "K", "mol", "cd", "rad", "factor", "offset")
VARIABLE = ("name", "valueReference", "type", "description", "causality", "variability",
            "initial", "start", "unit", "displayUnit", "quantity", "min", "max", "nominal",
            "unbounded", "relativeQuantity")  # fmt: skip


def _name(v: Any) -> str | None:
    return None if v is None else v.name


def _type(t: Any) -> tuple | None:
    if t is None:
        return None
    items = [(i.name, i.value, i.description) for i in t.items]
    return (t.name, t.type, t.unit, t.displayUnit, t.quantity, t.min, t.max, t.nominal,
            bool(t.relativeQuantity), items)  # fmt: skip


def _base(b: Any) -> tuple | None:
    return None if b is None else tuple(getattr(b, k) for k in BASE_UNIT)


def _unknowns(unknowns: list) -> list[tuple]:
    return [(_name(u.variable), _names(u.dependencies), u.dependenciesKind) for u in unknowns]


def _names(variables: list | None) -> list | None:
    return None if variables is None else [_name(v) for v in variables]


def summary(md: Any) -> dict[str, Any]:
    """The attributes, by part (``"model"``, ``"variables"``, ``"outputs"``, ...)."""
    fmi2 = md.fmiVersion == "2.0"
    ex = md.defaultExperiment
    cs = md.coSimulation
    return {
        "model": (md.fmiVersion, md.modelName, md.guid, md.description, md.author, md.version,
                  md.license, md.copyright, md.generationTool, md.generationDateAndTime,
                  md.variableNamingConvention,
                  # fmpy counts FMI 3's from the arrays' shapes; ours are FMI 2's only
                  (md.numberOfContinuousStates, md.numberOfEventIndicators) if fmi2 else None),
        "co-simulation": None if cs is None else tuple(getattr(cs, k) for k in CO_SIMULATION),
        "model exchange": None if md.modelExchange is None else md.modelExchange.modelIdentifier,
        "experiment": None if ex is None else (ex.startTime, ex.stopTime, ex.tolerance,
                                               ex.stepSize),
        "units": [(u.name, _base(u.baseUnit),
                   [(d.name, d.factor, d.offset) for d in u.displayUnits])
                  for u in md.unitDefinitions],
        "types": [_type(t) for t in md.typeDefinitions],
        "variables": [(*(getattr(v, k) for k in VARIABLE), _type(v.declaredType),
                       _name(v.derivative)) for v in md.modelVariables],
        "outputs": _unknowns(md.outputs),
        "derivatives": _unknowns(md.derivatives),
        "initial unknowns": _unknowns(md.initialUnknowns),
    }  # fmt: skip
