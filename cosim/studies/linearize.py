"""Linearise a co-simulation FMU from its own directional derivatives (fmpy only).

An FMU that exposes its continuous states (FMI 2 ``<Derivatives>``, FMI 3
``<ContinuousStateDerivative>``) and provides directional derivatives gives its state
Jacobian exactly, at the point its start values and parameters put it in, with one
``fmi2GetDirectionalDerivative`` (``fmi3GetDirectionalDerivative``) call per known:
``dx/dt = A x + B u``, ``y = C x + D u`` around that point. No model knowledge is
needed: the states, inputs and outputs come from the model description.
``glider-cosim analyze --from-fmu`` builds its continuous-time linearisation this way
from the plant FMU (:func:`glider_cosim.studies.analysis.analyze`).
"""

from __future__ import annotations

import shutil
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave


class LinearizationError(ValueError):
    """The FMU cannot be linearised this way (no states exposed, no directional
    derivatives, or a call failed: the message says which)."""


@dataclass(frozen=True)
class Linearization:
    """``dx/dt = A x + B u``, ``y = C x + D u`` (SI units of row over column) at a point.

    ``derivatives`` are the state derivatives' values there (all zero at an equilibrium).
    """

    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    derivatives: np.ndarray


def provides_directional_derivatives(fmu: Path | str) -> bool:
    """The co-simulation capability flag, FMI 2's ``providesDirectionalDerivative`` or
    FMI 3's ``providesDirectionalDerivatives`` (read from the XML: fmpy 0.3 reads FMI 3's
    as false)."""
    with zipfile.ZipFile(fmu) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    cs = root.find("CoSimulation")
    flag = "providesDirectionalDerivative" + ("s" if root.get("fmiVersion", "").startswith("3")
                                              else "")  # fmt: skip
    return cs is not None and cs.get(flag) in ("true", "1")


def linearize(fmu: Path | str, start: Mapping[str, float] | None = None) -> Linearization:
    """Instantiate ``fmu``, set ``start`` (parameters and start values, by name), initialise
    and return its linearisation from its directional derivatives.

    Raises
    ------
    LinearizationError
        If the FMU exposes no continuous states or provides no directional derivatives.
    fmpy.fmi1.FMICallException
        If an FMI call fails (the FMU refuses a value, say).
    """
    md = read_model_description(str(fmu))
    fmi3 = md.fmiVersion.startswith("3")
    cs = md.coSimulation
    if cs is None or not provides_directional_derivatives(fmu) or not md.derivatives:
        raise LinearizationError(
            f"{fmu}: expected a co-simulation FMU that exposes its continuous states and "
            "provides directional derivatives"
        )
    var = {v.name: v for v in md.modelVariables}
    states = tuple(u.variable.derivative.name for u in md.derivatives)
    ders = tuple(u.variable.name for u in md.derivatives)
    inputs = tuple(v.name for v in md.modelVariables if v.causality == "input")
    outputs = tuple(u.variable.name for u in md.outputs)
    folder = extract(str(fmu))
    try:
        slave = (FMU3Slave if fmi3 else FMU2Slave)(
            guid=md.guid, unzipDirectory=folder, modelIdentifier=cs.modelIdentifier,
            instanceName="linearize",
        )  # fmt: skip
        slave.instantiate()
        try:
            for name, value in (start or {}).items():
                if name not in var:
                    raise LinearizationError(f"{fmu}: it has no variable {name!r}")
                vr = [var[name].valueReference]
                if var[name].type == "Integer" or var[name].type == "Int32":
                    (slave.setInt32 if fmi3 else slave.setInteger)(vr, [int(value)])
                else:
                    (slave.setFloat64 if fmi3 else slave.setReal)(vr, [float(value)])
            if fmi3:
                slave.enterInitializationMode(startTime=0.0)
            else:
                slave.setupExperiment(startTime=0.0)
                slave.enterInitializationMode()
            slave.exitInitializationMode()
            known = [var[n].valueReference for n in states + inputs]
            rows = [var[n].valueReference for n in ders + outputs]
            J = np.empty((len(rows), len(known)))
            for j in range(len(known)):  # one column per known: a unit seed
                seed = [0.0] * len(known)
                seed[j] = 1.0
                J[:, j] = slave.getDirectionalDerivative(rows, known, seed)
            get = slave.getFloat64 if fmi3 else slave.getReal
            values = np.array(get([var[n].valueReference for n in ders]))
            slave.terminate()
        finally:
            slave.freeInstance()
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    n = len(states)
    return Linearization(states, inputs, outputs, J[:n, :n], J[:n, n:], J[n:, :n], J[n:, n:],
                         values)  # fmt: skip
