"""Component verification kit: reference cases per FMU, run on any FMU with the interface.

The cases are data, shipped in the package under ``verification/<component>/`` in the
FMI Cross-Check file layout (nothing in a case is executed):

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
    FMUs (``python -m glider_cosim.verify.kit --write`` regenerates them).

The comparison is a plain max-error test at the communication points: a case passes if
``|y - y_ref| <= atol + rtol * |y_ref|`` for every output and point (see the README,
"Verification kit", for why not fmpy's tube test).

Running a case goes through :data:`RUNNERS`, keyed by the FMU's FMI version; only FMI
2.0 co-simulation exists today (through :mod:`glider_cosim.master.cosimulation`).
"""

from __future__ import annotations

import argparse
import csv
import importlib.resources
import math
import re
import shutil
import time
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from glider_cosim.inputs.archives import InputFileError, read_fmu, regular_file
from glider_cosim.inputs.text import one_line, quote, shown_path


class VerifyInputError(ValueError):
    """Bad input to the kit (the FMU, the component, the case, a tolerance); one line."""


class CaseFileError(ValueError):
    """A case file of the kit cannot be read (names the file and what is wrong)."""


#: the components, their model names (our FMUs) and the kit's default case
COMPONENTS = {
    "plant": "GliderPlant",
    "observer": "GliderObserver",
    "controller": "GliderController",
}
#: the case exported as the cross-check case of each model (it uses no parameters)
DEFAULT_CASE = {"plant": "release", "observer": "filter_step", "controller": "passivity"}
OPT_REQUIRED = ("StartTime", "StopTime", "StepSize", "RelTol", "AbsTol")
_CASE_NAME = re.compile(r"[a-z][a-z0-9_]*")


def kit_root() -> Path:
    """The shipped cases' folder (inside the installed package)."""
    return Path(str(importlib.resources.files("glider_cosim") / "verification"))


# ---------------------------------------------------------------------------- cases
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


# -------------------------------------------------------------------------- running
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


def _run_case(fmu: Path, md: Any, case: Case, record: Sequence[str]) -> Run:
    """Run ``case`` on an FMI 2.0 or 3.0 co-simulation FMU with our master."""
    from glider_cosim.master.cosimulation import CoSimulation
    from glider_cosim.master.errors import FMUCallError, FMUStopped
    from glider_cosim.master.spec import System
    from glider_cosim.runner.recorders import ArrayRecorder

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
    "2.0": _run_case,
    "3.0": _run_case,
}


def _fmi_version(path: Path) -> str | None:
    try:
        with zipfile.ZipFile(path) as z:
            head = z.read("modelDescription.xml")[:4000].decode("utf-8", "replace")
    except (OSError, KeyError, zipfile.BadZipFile, ValueError):
        return None
    m = re.search(r'fmiVersion\s*=\s*"([^"]*)"', head)
    return m.group(1) if m else None


def open_fmu(fmu: str | Path) -> Any:
    """Check ``fmu`` and return its model description (one-line error if it cannot run)."""
    path = Path(fmu)
    try:
        regular_file(path, "verify", "FMU")
        version = _fmi_version(path)
        if version is not None and version not in RUNNERS:
            raise VerifyInputError(
                f"verify: FMU {quote(path.name)} is an FMI {version} FMU: this build runs "
                f"FMI {', '.join(RUNNERS)} co-simulation FMUs"
            )
        return read_fmu(path, "verify")
    except InputFileError as err:
        raise VerifyInputError(str(err)) from None


# ------------------------------------------------------------------------ comparing
@dataclass
class CaseResult:
    """The outcome of one case: pass/fail, the worst variable and where."""

    case: Case
    passed: bool
    variable: str | None
    max_error: float
    tolerance: float
    time: float | None
    value: float | None
    ref_value: float | None
    seconds: float
    note: str = ""
    rtol: float = 0.0
    atol: float = 0.0

    def describe(self, fmu: str = "") -> str:
        """One readable line: case, variable, time, values, error against tolerance."""
        head = f"{fmu + ': ' if fmu else ''}{self.case.component} case {self.case.name!r}"
        verdict = "passes" if self.passed else "fails"
        parts = [f"{head} {verdict}"]
        if self.variable is not None and self.time is not None:
            rel = "<=" if self.max_error <= self.tolerance else ">"
            parts.append(
                f"{self.variable} = {self.value:.10g} at t = {self.time:.6g} s, reference "
                f"{self.ref_value:.10g}: error {self.max_error:.3g} {rel} tolerance "
                f"{self.tolerance:.3g} (rtol {self.rtol:g}, atol {self.atol:g})"
            )
        if self.note:
            parts.append(self.note)
        return "; ".join(parts)


def compare(case: Case, run: Run, rtol: float | None = None, atol: float | None = None):
    """Compare a run with the case's reference (max-error test at every point)."""
    rtol = case.rtol if rtol is None else rtol
    atol = case.atol if atol is None else atol
    ref = case.reference
    assert ref is not None
    notes = []
    passed = True
    n = min(len(ref), len(run.data))
    expected_end = case.discard_time
    if expected_end is not None:
        if run.stop is None or run.stop[0] != "discard":
            passed = False
            got = "ran to the stop time" if run.stop is None else run.stop[2]
            notes.append(f"expected fmi2Discard at t = {expected_end:g} s, {got}")
        elif abs(run.stop[1] - expected_end) > case.step * (1 + 1e-9):
            passed = False
            notes.append(
                f"fmi2Discard at t = {run.stop[1]:g} s, expected at {expected_end:g} s "
                f"(within one step, {case.step:g} s)"
            )
        else:
            notes.append(f"fmi2Discard at t = {run.stop[1]:g} s as expected")
    elif run.stop is not None:
        passed = False
        notes.append(f"stopped at t = {run.stop[1]:g} s: {run.stop[2]}")
    elif len(run.data) != len(ref):
        passed = False
        notes.append(f"{len(run.data)} rows, reference {len(ref)}")
    if n and np.max(np.abs(run.data[:n, 0] - ref[:n, 0])) > 1e-9 * max(1.0, case.stop):
        passed = False
        notes.append("communication points differ from the reference")
    worst = (-1.0, None, 0.0, 0.0, None, None, None)
    col = {c: i for i, c in enumerate(run.columns)}
    for j, name in enumerate(case.ref_columns[1:], start=1):
        y = run.data[:n, col[name]]
        y_ref = ref[:n, j]
        err = np.abs(y - y_ref)
        err = np.where(np.isfinite(err), err, np.inf)
        tol = atol + rtol * np.abs(y_ref)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(tol > 0, err / tol, np.where(err > 0, np.inf, 0.0))
        if not len(ratio):
            continue
        k = int(np.argmax(ratio))
        if ratio[k] > worst[0] or worst[1] is None:
            worst = (ratio[k], name, err[k], tol[k], ref[k, 0], y[k], y_ref[k])
    _, var, err, tol, t, y, y_ref = worst
    if var is not None and not err <= tol:
        passed = False
    return CaseResult(case, passed, var, float(err), float(tol), t, y, y_ref, run.seconds,
                      "; ".join(notes), rtol, atol)  # fmt: skip


# ------------------------------------------------------------------- the front door
def check_tolerance(value: Any, name: str) -> float | None:
    """``None`` or a finite number >= 0; else :class:`VerifyInputError` (one line)."""
    if value is None:
        return None
    if isinstance(value, str):
        try:
            number = float(value)
        except ValueError:
            number = math.nan
    elif isinstance(value, bool) or not isinstance(value, int | float):
        number = math.nan
    else:
        number = float(value)
    if not (math.isfinite(number) and number >= 0):
        raise VerifyInputError(f"{name} {quote(value)} is invalid: expected a finite number >= 0")
    return number


def _interface(component: str, cases: Sequence[str], root: Path | None) -> dict[str, str]:
    out: dict[str, str] = {}
    for name in cases:
        out.update(load_case(component, name, root, with_reference=False).variables)
        cols, _ = read_table((root or kit_root()) / component / f"{name}_ref.csv")
        out.update({c: "output" for c in cols[1:]})
    return out


def _missing(md: Any, needed: dict[str, str]) -> list[str]:
    have = {v.name: v.causality for v in md.modelVariables}
    out = []
    for name, causality in needed.items():
        got = have.get(name)
        if got is None:
            out.append(f"{name} ({causality})")
        elif got != causality:
            out.append(f"{name} (is {got}, expected {causality})")
    return out


def detect_component(md: Any, root: Path | None = None) -> str:
    """The component whose inputs and outputs the FMU has (the best match)."""
    have = {(v.name, v.causality) for v in md.modelVariables}
    scores = {}
    for component in COMPONENTS:
        io = {n: c for n, c in _interface(component, case_names(component, root), root).items()
              if c in ("input", "output")}  # fmt: skip
        scores[component] = sum((n, c) in have for n, c in io.items()) / len(io)
    best = max(scores, key=lambda c: scores[c])
    if scores[best] == 0:
        raise VerifyInputError(
            f"verify: FMU {quote(md.modelName)} has none of the inputs and outputs of a "
            f"component ({', '.join(COMPONENTS)}): expected e.g. the {best} interface"
        )
    return best


@dataclass
class Report:
    """The results of :func:`verify`."""

    fmu: Path
    model_name: str
    component: str
    results: list[CaseResult] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return all(r.passed for r in self.results)

    def table(self) -> str:
        """One row per case: pass/fail, worst variable, max error vs tolerance, time."""
        head = ("case", "result", "worst variable", "max error", "tolerance", "at t (s)",
                "run (s)", "note")  # fmt: skip
        rows = [head]
        for r in self.results:
            rows.append((
                r.case.name, "pass" if r.passed else "FAIL", r.variable or "-",
                f"{r.max_error:.3g}", f"{r.tolerance:.3g}",
                "-" if r.time is None else f"{r.time:.6g}", f"{r.seconds:.2f}", r.note,
            ))  # fmt: skip
        widths = [max(len(row[i]) for row in rows) for i in range(len(head) - 1)]
        lines = ["  ".join(c.ljust(w) for c, w in zip(row, widths)) + "  " + row[-1]
                 for row in rows]  # fmt: skip
        n_fail = sum(not r.passed for r in self.results)
        lines.append(
            f"{self.component} ({self.model_name}, {shown_path(self.fmu)}): "
            f"{len(self.results) - n_fail} of {len(self.results)} cases pass"
        )
        return "\n".join(line.rstrip() for line in lines)


def verify(
    fmu: str | Path,
    component: str | None = None,
    case: str | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    root: Path | None = None,
) -> Report:
    """Run the cases of a component on ``fmu`` and compare with the references.

    Parameters
    ----------
    fmu : path
        Any FMI 2.0 co-simulation FMU with the component's interface (variables looked
        up by name in its model description).
    component : str, optional
        ``plant``, ``observer`` or ``controller``; found from the variables if omitted.
    case : str, optional
        One case (default: every case of the component).
    rtol, atol : float, optional
        Override every case's tolerances (finite, >= 0).
    root : Path, optional
        Another kit folder (default: the shipped cases).

    Raises
    ------
    VerifyInputError
        Not a usable FMU, unknown component or case, a bad tolerance, or variables of the
        interface missing (all named, in one line).
    """
    rtol = check_tolerance(rtol, "rtol")
    atol = check_tolerance(atol, "atol")
    if component is not None and component not in COMPONENTS:
        raise VerifyInputError(
            f"component {quote(component)} is unknown: expected one of {', '.join(COMPONENTS)}"
        )
    path = Path(fmu)
    md = open_fmu(path)
    component = component or detect_component(md, root)
    names = case_names(component, root)
    if case is not None:
        if case not in names:
            raise VerifyInputError(
                f"case {quote(case)} is unknown for the {component}: expected one of "
                f"{', '.join(names)}"
            )
        names = [case]
    missing = _missing(md, _interface(component, names, root))
    if missing:
        raise VerifyInputError(
            f"verify: FMU {quote(path.name)} ({md.modelName}) lacks the {component} interface: "
            f"missing {', '.join(missing)}"
        )
    report = Report(path, md.modelName, component)
    runner = RUNNERS[md.fmiVersion]
    for name in names:
        c = load_case(component, name, root)
        try:
            run = runner(path, md, c, c.ref_columns[1:])
        except CaseFileError:
            raise
        except ValueError as err:  # e.g. a parameter out of the FMU's declared range
            raise VerifyInputError(f"case {name}: {one_line(err)}") from None
        report.results.append(compare(c, run, rtol, atol))
    return report


# --------------------------------------------------------------- references, export
def write_references(fmu_dir: str | Path | None = None, dest: Path | None = None) -> list[Path]:
    """Run every case on our FMUs (built if missing or stale) and write ``_ref.csv`` and the
    ``DiscardTime`` of ``_ref.opt``.

    ``dest`` (default: the shipped kit) receives a complete copy of the kit with the new
    references; the shipped case definitions are read from the shipped kit.
    """
    from glider_cosim.build.folders import build_all, fmu_folder

    fmus = build_all(fmu_folder(fmu_dir), only_stale=True)
    src = kit_root()
    dest = src if dest is None else Path(dest)
    written = []
    for component, model in COMPONENTS.items():
        (dest / component).mkdir(parents=True, exist_ok=True)
        if dest != src:
            for p in (src / component).iterdir():
                if p.is_file() and not p.name.endswith("_ref.csv"):
                    shutil.copyfile(p, dest / component / p.name)
        md = open_fmu(fmus[model])
        outputs = [v.name for v in md.modelVariables if v.causality == "output"]
        for name in case_names(component, src):
            c = load_case(component, name, src, with_reference=False)
            run = _run_case(fmus[model], md, c, outputs)
            if run.stop is not None and run.stop[0] != "discard":
                raise RuntimeError(f"{component} case {name}: {run.stop[2]}")
            ref = dest / component / f"{name}_ref.csv"
            ref.write_text(table_text(run.columns, run.data))
            opt = dest / component / f"{name}_ref.opt"
            lines = [ln for ln in opt.read_text().splitlines() if not ln.startswith("DiscardTime")]
            if run.stop is not None:
                lines.append(f"DiscardTime, {run.stop[1]!r}")
            opt.write_text("\n".join(lines) + "\n")
            written += [ref, opt]
    return written


def table_text(columns: Sequence[str], data: np.ndarray) -> str:
    """A CSV table, every number in its shortest exact form."""
    lines = [",".join(columns)]
    lines += [",".join(repr(float(v)) for v in row) for row in data]
    return "\n".join(lines) + "\n"


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("glider-cosim")
    except PackageNotFoundError:  # pragma: no cover - run from a plain checkout
        return "0+unknown"


def export(out: str | Path, fmu_dir: str | Path | None = None, platform: str = "linux64") -> Path:
    """Write the kit with our FMUs in the FMI Cross-Check layout; return the vendor folder.

    ``<out>/fmus/2.0/cs/<platform>/glider-cosim/<version>/<Model>/`` holds ``<Model>.fmu``
    and the default case as ``<Model>_in.csv``, ``<Model>_ref.csv``, ``<Model>_ref.opt``
    and ``ReadMe.txt``; every case (the default one too) is also in
    ``<Model>/cases/<case>/`` under the same file names, with ``<Model>_par.csv`` where the
    case sets parameters. Cross-check tools find one FMU per model folder and run the
    default case; the subfolders hold no FMU and are not picked up by them.
    """
    from glider_cosim.build.folders import build_all, fmu_folder

    fmus = build_all(fmu_folder(fmu_dir), only_stale=True)
    base = Path(out) / "fmus" / "2.0" / "cs" / platform / "glider-cosim" / _version()
    for component, model in COMPONENTS.items():
        folder = base / model
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        shutil.copyfile(fmus[model], folder / f"{model}.fmu")
        src = kit_root() / component
        names = case_names(component)
        purposes = _purposes(src / "README.md")
        md = open_fmu(fmus[model])
        for name in names:
            sub = folder / "cases" / name
            sub.mkdir(parents=True)
            for suffix in ("_in.csv", "_ref.csv", "_ref.opt", "_par.csv"):
                if (src / f"{name}{suffix}").is_file():
                    shutil.copyfile(src / f"{name}{suffix}", sub / f"{model}{suffix}")
            (sub / "ReadMe.txt").write_text(_readme(model, component, name, purposes, md))
        default = DEFAULT_CASE[component]
        for suffix in ("_in.csv", "_ref.csv", "_ref.opt"):
            shutil.copyfile(
                folder / "cases" / default / f"{model}{suffix}", folder / f"{model}{suffix}"
            )
        text = _readme(model, component, default, purposes, md)
        others = ", ".join(n for n in names if n != default)
        text += (
            f"\nThe other cases of this model are in cases/<case>/ with the same file names "
            f"(run them with this FMU; set the parameters of {model}_par.csv where there is "
            f"one): {others}.\n"
        )
        (folder / "ReadMe.txt").write_text(text)
    return base


def _purposes(readme: Path) -> dict[str, str]:
    out = {}
    for line in readme.read_text().splitlines():
        m = re.match(r"\| `([a-z0-9_]+)` \| (.*?) \|", line)
        if m:
            out[m.group(1)] = m.group(2)
    return out


def _readme(model: str, component: str, name: str, purposes: dict[str, str], md: Any) -> str:
    case = load_case(component, name)
    lines = [
        f"{model} (glider-cosim {_version()}), {component} case '{name}': {purposes.get(name, '')}",
        "",
        f"Co-simulation from {case.start:g} s to {case.stop:g} s with a fixed communication "
        f"step of {case.step:g} s; the inputs of {model}_in.csv are held from each row's time "
        "to the next.",
        f"Comparison at every communication point: |y - y_ref| <= AbsTol + RelTol * |y_ref| "
        f"with RelTol = {case.rtol:g}, AbsTol = {case.atol:g} (SI units).",
    ]
    if case.parameters:
        pars = ", ".join(f"{k} = {v}" for k, v in case.parameters.items())
        lines.append(f"Parameters to set before initialisation ({model}_par.csv): {pars}.")
    else:
        lines.append("No parameters: the FMU's start values.")
    if case.discard_time is not None:
        lines.append(
            f"Expected end: the FMU returns fmi2Discard from the doStep that starts at "
            f"t = {case.discard_time:g} s (DiscardTime in {model}_ref.opt; within one step)."
        )
    feedthrough = [
        u.variable.name
        for u in md.outputs
        if u.dependencies is None or any(d.causality == "input" for d in u.dependencies)
    ]
    if feedthrough:
        lines.append(
            f"{', '.join(feedthrough)} depends directly on the inputs: the reference records it "
            "after the inputs of the same communication point are set (row k uses the inputs "
            "of row k). A tool that records outputs before it sets the inputs of the point "
            "(e.g. fmpy's simulate_fmu) shows the same values one row later."
        )
    lines.append("Checked with: glider-cosim verify " + f"{model}.fmu --case {name}")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------ commands
def add_arguments(p: argparse.ArgumentParser, tolerance: Callable[[str], float]) -> None:
    """The options of ``glider-cosim verify`` (shared with ``python -m``)."""
    p.add_argument("fmu", nargs="?", default=None, help="the FMU to verify")
    p.add_argument(
        "--component",
        choices=tuple(COMPONENTS),
        default=None,
        help="plant, observer or controller (default: found from the variables)",
    )
    p.add_argument("--case", default=None, help="one case (default: every case)")
    p.add_argument(
        "--rtol",
        type=tolerance,
        default=None,
        help="relative tolerance for every case (default: each case's)",
    )
    p.add_argument(
        "--atol",
        type=tolerance,
        default=None,
        help="absolute tolerance for every case, SI units (default: each case's)",
    )
    p.add_argument(
        "--write-references",
        action="store_true",
        help="rerun the cases on our FMUs and rewrite the shipped references",
    )
    p.add_argument(
        "--export",
        default=None,
        metavar="DIR",
        help="write the cases with our FMUs in the FMI Cross-Check layout",
    )
    p.add_argument(
        "--fmu-dir",
        default=None,
        help="our FMUs for --write-references/--export, built if missing or stale "
        "(default: the per-user cache)",
    )


def run_command(args: argparse.Namespace) -> int:
    """``glider-cosim verify``: 0 all cases pass, 1 any fails; VerifyInputError -> 2."""
    if args.write_references or args.export:
        if args.fmu is not None:
            raise VerifyInputError("verify: give an FMU or --write-references/--export, not both")
        if args.write_references:
            files = write_references(args.fmu_dir)
            print(f"wrote {len(files)} files under {kit_root()}")
        if args.export:
            print(f"wrote {export(args.export, args.fmu_dir)}")
        return 0
    if args.fmu is None:
        raise VerifyInputError("verify: expected an FMU (or --write-references, --export DIR)")
    report = verify(args.fmu, args.component, args.case, args.rtol, args.atol)
    print(report.table())
    return 0 if report.passed else 1


def _tolerance(text: str) -> float:
    try:
        value = check_tolerance(text, "")
    except VerifyInputError:
        raise argparse.ArgumentTypeError(
            f"{quote(text)} is invalid: expected a finite number >= 0"
        ) from None
    assert value is not None
    return value
