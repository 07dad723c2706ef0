"""Running one FMI-LS-REF experiment with fmpy (``FMU2Slave``/``FMU3Slave``): parameters
set before initialisation, the stimuli held from each row's time to the next (the
start's row set in initialisation mode), the outputs read after the inputs of each
communication point are set."""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any

import numpy as np

from ..inputs.text import one_line, quote
from .lsref_report import LsrefFileError, Planned

_SETTERS = {
    "Real": "setReal",
    "Float64": "setFloat64",
    "Float32": "setFloat32",
    "Integer": "setInteger",
    "Int32": "setInt32",
    "Boolean": "setBoolean",
}
_GETTERS = {k: v.replace("set", "get", 1) for k, v in _SETTERS.items()}


def _typed(var: Any, text: str, where: str) -> float | int | bool:
    from ..inputs.ssp_files import parse_value

    kind = {"Float64": "Real", "Float32": "Real", "Int32": "Integer"}.get(var.type, var.type)
    return parse_value(text.strip(), kind, where)


def simulate(fmu: Path, md: Any, unzipdir: str, ex: Planned) -> tuple[np.ndarray, str]:
    """Run one experiment with fmpy; (rows of time + the references' variables at every
    communication point reached, a note: empty, or how the run ended early)."""
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    where = f"{ex.file}: experiment {quote(ex.name)}"
    variables = {v.name: v for v in md.modelVariables}
    ref_cols = ex.references[0][1:] if ex.references else []
    stim_cols = ex.stimuli[0][1:] if ex.stimuli else []
    for name in [*stim_cols, *ref_cols, *ex.parameters]:
        if name not in variables:
            raise LsrefFileError(f"{where}: {quote(name)} is not a variable of {md.modelName}")
    for name in stim_cols:
        if variables[name].causality not in ("input", "parameter"):
            raise LsrefFileError(
                f"{where}: stimulus {quote(name)} is a "
                f"{variables[name].causality}, expected an input"
            )
    for name in [*stim_cols, *ref_cols, *ex.parameters]:
        if variables[name].type not in _SETTERS:
            raise LsrefFileError(
                f"{where}: {quote(name)} is of type {variables[name].type}: "
                "expected Real, Integer or Boolean"
            )
    fmi3 = str(md.fmiVersion).startswith("3")
    common = {
        "guid": md.guid,  # fmpy keeps an FMI 3 FMU's instantiationToken there too
        "unzipDirectory": unzipdir,
        "modelIdentifier": md.coSimulation.modelIdentifier,
        "instanceName": "lsref",
    }
    slave = FMU3Slave(**common) if fmi3 else FMU2Slave(**common)

    def put(name: str, value: Any) -> None:
        v = variables[name]
        getattr(slave, _SETTERS[v.type])([v.valueReference], [value])

    n = int(round((ex.stop - ex.start) / ex.step))
    rows: list[list[float]] = []
    note = ""
    stim_t = ex.stimuli[1][:, 0] if ex.stimuli else None
    slave.instantiate()
    try:
        last = -1

        def drive(t: float) -> None:  # the stimuli's row in effect at t, set once
            nonlocal last
            if stim_t is None:
                return
            i = int(np.searchsorted(stim_t, t + 1e-9 * ex.step, "right")) - 1
            if i >= 0 and i != last:
                for j, c in enumerate(stim_cols, start=1):
                    value = ex.stimuli[1][i, j]
                    kind = variables[c].type
                    put(
                        c,
                        bool(value)
                        if kind == "Boolean"
                        else int(round(value))
                        if kind in ("Integer", "Int32")
                        else float(value),
                    )
                last = i

        try:
            if not fmi3:
                slave.setupExperiment(startTime=ex.start)
            for name, (_, text) in ex.parameters.items():
                put(name, _typed(variables[name], text, f"{where}: parameter {quote(name)}"))
            if fmi3:
                slave.enterInitializationMode(startTime=ex.start)
            else:
                slave.enterInitializationMode()
            drive(ex.start)  # the inputs at the start take part in the initialisation
            slave.exitInitializationMode()
        except FMICallException as err:
            return np.empty((0, 1 + len(ref_cols))), f"initialisation failed: {one_line(err)}"
        vrs = [variables[c].valueReference for c in ref_cols]
        kinds = [variables[c].type for c in ref_cols]
        for k in range(n + 1):
            t = ex.start + k * ex.step
            try:
                drive(t)
                rows.append([t, *(float(getattr(slave, _GETTERS[kind])([vr])[0])
                                  for vr, kind in zip(vrs, kinds))])  # fmt: skip
                if k < n:
                    slave.doStep(t, ex.step)
            except FMICallException as err:
                note = f"the FMU stopped at t = {t:g} s: {one_line(err)}"
                break
        if not note:
            slave.terminate()
    finally:
        with contextlib.suppress(FMICallException):  # an FMU that failed may refuse it
            slave.freeInstance()
    return np.array(rows, dtype=float).reshape(-1, 1 + len(ref_cols)), note
