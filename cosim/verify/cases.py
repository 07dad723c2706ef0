"""The verification kit's cases: their files, read into a :class:`Case` (data, never run).

The cases are data, shipped in the package under ``verification/<component>/`` in the
FMI Cross-Check file layout:

``<Case>_in.csv``
    ``time`` and one column per input, one row per communication point (each value is
    held from its time to the next row's).
``<Case>_par.csv`` (optional)
    ``name,value`` rows: parameters set before initialisation (numbers, ``true``/
    ``false``); the FMU's model description gives their types.
``<Case>_ref.opt``
    ``StartTime``, ``StopTime``, ``StepSize``, ``RelTol`` (the comparison's relative
    tolerance), ``AbsTol`` (its absolute tolerance, SI units) and, for a case whose
    expected end is an ``fmi2Discard``, ``DiscardTime`` (the communication point the
    discarded step starts from). The file stays readable by fmpy's ``read_ref_opt_file``.
``<Case>_ref.csv``
    ``time`` and the outputs compared, from the Python reference models run as our
    FMUs (``python -m glider_cosim.verify --write`` regenerates them).
"""

from __future__ import annotations

import csv
import importlib.resources
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..components import COMPONENTS as REGISTERED
from ..inputs.text import one_line, quote, shown_path

if TYPE_CHECKING:  # numpy is imported where a table is read: the CLI's parser imports this
    import numpy as np


class VerifyInputError(ValueError):
    """Bad input to the kit (the FMU, the component, the case, a tolerance); one line."""


class CaseFileError(ValueError):
    """A case file of the kit cannot be read (names the file and what is wrong)."""


#: the kit's components (those whose ``component.toml`` has a ``[kit]`` table) and their
#: model names (our FMUs), from the component registry
COMPONENTS = {c.name: c.model for c in REGISTERED if c.core}


#: each component's core interface: the variables without which no case can run (every
#: case of the component needs them; the cases named in CORE_CASES need nothing more)
CORE: dict[str, dict[str, str]] = {c.name: dict(c.core) for c in REGISTERED if c.core}


#: the case exported as the cross-check case of each model (it uses no parameters)
DEFAULT_CASE = {c.name: c.default_case for c in REGISTERED if c.core and c.default_case}


OPT_REQUIRED = ("StartTime", "StopTime", "StepSize", "RelTol", "AbsTol")


_CASE_NAME = re.compile(r"[a-z][a-z0-9_]*")


def kit_root() -> Path:
    """The shipped cases' folder (inside the installed package)."""
    return Path(str(importlib.resources.files("glider_cosim") / "verification"))


@dataclass
class Case:
    """One reference case, read from its files."""

    component: str
    name: str
    folder: Path
    start: float
    stop: float
    step: float
    rtol: float
    atol: float
    discard_time: float | None
    parameters: dict[str, str]
    input_columns: list[str]
    inputs: np.ndarray
    ref_columns: list[str]
    reference: np.ndarray | None

    @property
    def variables(self) -> dict[str, str]:
        """Every variable the case uses -> the causality it needs."""
        out = {n: "input" for n in self.input_columns[1:]}
        out.update({n: "parameter" for n in self.parameters})
        out.update({n: "output" for n in self.ref_columns[1:]})
        return out


def read_table(path: Path) -> tuple[list[str], np.ndarray]:
    """A cross-check CSV: header ``time,...``, numbers; (columns, rows)."""
    import numpy as np

    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except OSError as err:
        raise CaseFileError(f"{shown_path(path)}: cannot be read ({err.strerror})") from None
    if not rows or not rows[0] or rows[0][0] != "time":
        raise CaseFileError(f"{shown_path(path)}: expected a header starting with 'time'")
    cols = rows[0]
    try:
        data = np.array([[float(v) for v in r] for r in rows[1:] if r], dtype=float)
    except ValueError as err:
        raise CaseFileError(f"{shown_path(path)}: {one_line(err)}") from None
    if data.ndim != 2 or data.shape[1] != len(cols) or len(data) < 1:
        raise CaseFileError(f"{shown_path(path)}: every row needs {len(cols)} numbers")
    if not np.all(np.isfinite(data)) or np.any(np.diff(data[:, 0]) <= 0):
        raise CaseFileError(f"{shown_path(path)}: values must be finite, times increasing")
    return cols, data


def read_opt(path: Path) -> dict[str, float]:
    """``Key, value`` lines (fmpy's ``_ref.opt`` format); the required keys checked."""
    opts: dict[str, float] = {}
    try:
        lines = path.read_text().splitlines()
    except OSError as err:
        raise CaseFileError(f"{shown_path(path)}: cannot be read ({err.strerror})") from None
    for line in lines:
        if not line.strip():
            continue
        key, sep, value = line.partition(",")
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        opts[key.strip()] = number
        if not sep or not math.isfinite(number):
            raise CaseFileError(f"{shown_path(path)}: line {quote(line)}: expected 'Key, number'")
    missing = [k for k in OPT_REQUIRED if k not in opts]
    if missing:
        raise CaseFileError(f"{shown_path(path)}: missing {', '.join(missing)}")
    return opts


def read_parameters(path: Path) -> dict[str, str]:
    """``name,value`` rows of a ``_par.csv`` (values kept as text until the type is known)."""
    if not path.is_file():
        return {}
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f) if r]
    if not rows or rows[0] != ["name", "value"] or any(len(r) != 2 for r in rows):
        raise CaseFileError(f"{shown_path(path)}: expected a header 'name,value' and 2 columns")
    return {name: value for name, value in rows[1:]}


def case_names(component: str, root: Path | None = None) -> list[str]:
    """The cases of a component, the default case first, then by name."""
    folder = (root or kit_root()) / component
    names = sorted(p.name[: -len("_ref.opt")] for p in folder.glob("*_ref.opt"))
    default = DEFAULT_CASE.get(component)
    return sorted(names, key=lambda n: (n != default, n))


def load_case(
    component: str, name: str, root: Path | None = None, with_reference: bool = True
) -> Case:
    """Read a case from its files (``with_reference=False``: without ``_ref.csv``)."""
    folder = (root or kit_root()) / component
    opts = read_opt(folder / f"{name}_ref.opt")
    in_cols, inputs = read_table(folder / f"{name}_in.csv")
    ref_cols: list[str] = []
    ref = None
    if with_reference:
        ref_cols, ref = read_table(folder / f"{name}_ref.csv")
    return Case(
        component=component,
        name=name,
        folder=folder,
        start=opts["StartTime"],
        stop=opts["StopTime"],
        step=opts["StepSize"],
        rtol=opts["RelTol"],
        atol=opts["AbsTol"],
        discard_time=opts.get("DiscardTime"),
        parameters=read_parameters(folder / f"{name}_par.csv"),
        input_columns=in_cols,
        inputs=inputs,
        ref_columns=ref_cols,
        reference=ref,
    )


def kit_files(root: Path | None = None) -> list[Path]:
    """Every file of the kit (cases and readmes)."""
    root = root or kit_root()
    return sorted(p for c in COMPONENTS for p in (root / c).iterdir() if p.is_file())
