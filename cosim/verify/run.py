"""Running a verification case on an FMU with our master: inputs, parameters, how it ends.

Running a case goes through :data:`RUNNERS`, keyed by the FMU's FMI version; FMI 2.0
and 3.0 co-simulation exist today (through :mod:`glider_cosim.master.cosimulation`).
"""

from __future__ import annotations

import math
import re
import time
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..inputs.archives import InputFileError, read_fmu, regular_file
from ..inputs.text import one_line, quote
from .cases import Case, CaseFileError, VerifyInputError


@dataclass
class Run:
    """What an FMU produced on a case: recorded rows and how the run ended."""

    columns: list[str]
    data: np.ndarray
    #: None: ran to StopTime; else ("discard" | "error", time of the failed step, message)
    stop: tuple[str, float, str] | None = None
    seconds: float = 0.0


#: FMI 3.0 types as the FMI 2.0 ones the cases use
_KIND = {"Float64": "Real", "Int32": "Integer"}


def _value(text: str, var: Any, where: str) -> float | int | bool:
    """A parameter's text as the variable's FMI type."""
    t = text.strip()
    kind = _KIND.get(var.type, var.type)
    if kind == "Boolean":
        if t.lower() in ("true", "1"):
            return True
        if t.lower() in ("false", "0"):
            return False
    elif kind == "Integer":
        if re.fullmatch(r"[+-]?\d{1,10}", t) and -(2**31) <= int(t) < 2**31:
            return int(t)
    elif kind == "Real":
        try:
            v = float(t)
        except ValueError:
            v = math.nan
        if math.isfinite(v):
            return v
    raise CaseFileError(f"{where}: {quote(text)} is not a valid {var.type} value")


def run_case(fmu: Path, md: Any, case: Case, record: Sequence[str]) -> Run:
    """Run ``case`` on an FMI 2.0 or 3.0 co-simulation FMU with our master."""
    from ..master.cosimulation import CoSimulation
    from ..master.errors import FMUCallError, FMUStopped
    from ..master.spec import System
    from ..runner.recorders import ArrayRecorder

    variables = {v.name: v for v in md.modelVariables}
    params = {
        n: _value(v, variables[n], f"{case.name}_par.csv: {n}") for n, v in case.parameters.items()
    }
    times = list(case.inputs[:, 0])
    tables = {
        f"fmu.{c}": (times, list(case.inputs[:, i + 1]))
        for i, c in enumerate(case.input_columns[1:])
    }
    # inputs the case does not drive (a third-party FMU's extras) stay at their start value
    driven = {
        f"fmu.{v.name}": float(v.start or 0.0)
        for v in md.modelVariables
        if v.causality == "input"
        and v.name not in case.input_columns
        and _KIND.get(v.type, v.type) == "Real"
    }
    system = System(
        fmus={"fmu": fmu},
        connections=[],
        parameters={"fmu": params},
        driven=driven,
        tables=tables,
        record=[f"fmu.{n}" for n in record],
    )
    sim = CoSimulation(system, step=case.step, start_time=case.start)
    rec = ArrayRecorder()
    stop = None
    t0 = time.perf_counter()
    try:
        sim.run(case.stop, rec)
    except FMUStopped as err:
        stop = ("discard", err.time, one_line(err))
    except FMUCallError as err:
        stop = ("error", err.time, one_line(err))
    finally:
        sim.close()
    cols = [c.removeprefix("fmu.") for c in rec.columns] or ["time", *record]
    return Run(cols, rec.array(len(cols)), stop, time.perf_counter() - t0)


#: FMI version of the model description -> runner (our master runs both)
RUNNERS: dict[str, Callable[[Path, Any, Case, Sequence[str]], Run]] = {
    "2.0": run_case,
    "3.0": run_case,
}


def _fmi_version(path: Path) -> str | None:
    try:
        with zipfile.ZipFile(path) as z:
            head = z.read("modelDescription.xml")[:4000].decode("utf-8", "replace")
    except (OSError, KeyError, zipfile.BadZipFile, ValueError):
        return None
    m = re.search(r'fmiVersion\s*=\s*"([^"]*)"', head)
    return m.group(1) if m else None


def _refuse_ssp(path: Path) -> None:
    """Raise :class:`VerifyInputError` naming ``path`` as an SSP (an ``.ssd`` file, or a
    zip with ``SystemStructure.ssd``) and what to pass instead: one of its FMUs."""
    try:
        with zipfile.ZipFile(path) as z:
            names = z.namelist()
    except (OSError, zipfile.BadZipFile, ValueError):
        names = None
    if names is None and path.suffix.lower() == ".ssd":
        what, fmus = "an SSP system description (.ssd)", []
    elif names is not None and "SystemStructure.ssd" in names:
        what, fmus = "an SSP (a system of FMUs)", [n for n in names if n.endswith(".fmu")]
    else:
        return
    inside = f" ({', '.join(fmus)}, unzipped from it)" if fmus else ""
    raise VerifyInputError(
        f"{quote(path.name)} is {what}, not an FMU: verify one of its FMUs{inside}; "
        f"run the whole system with glider-cosim run {path}"
    )


def open_fmu(fmu: str | Path) -> Any:
    """Check ``fmu`` and return its model description (one-line error if it cannot run)."""
    path = Path(fmu)
    try:
        regular_file(path, None, "FMU")
        _refuse_ssp(path)
        version = _fmi_version(path)
        if version is not None and version not in RUNNERS:
            raise VerifyInputError(
                f"FMU {quote(path.name)} is an FMI {version} FMU: this build runs "
                f"FMI {', '.join(RUNNERS)} co-simulation FMUs"
            )
        return read_fmu(path, None)
    except InputFileError as err:
        raise VerifyInputError(str(err)) from None
