"""Comparing an FMU's runs with the verification kit's references: :func:`verify` and its report.

The comparison is a plain max-error test at the communication points: a case passes if
``|y - y_ref| <= atol + rtol * |y_ref|`` for every output and point (see the README,
"Verification kit", for why not fmpy's tube test).
"""

from __future__ import annotations

import hashlib
import math
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..inputs.archives import binary_path
from ..inputs.text import one_line, quote, shown_path
from ..runner.provenance import file_sha256, zip_flavor
from .cases import (
    COMPONENTS,
    CORE,
    Case,
    CaseFileError,
    VerifyInputError,
    case_names,
    kit_root,
    load_case,
    read_table,
)
from .loop import LoopReport, loop_checks
from .run import RUNNERS, Run, open_fmu


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


#: the note of a case whose outputs equal the reference one communication step late
ONE_STEP_LATE = (
    "the outputs equal the reference one step ({step:g} s) late: they are computed in "
    "doStep, not from the inputs when read (docs/how-to/verify-a-component.md, "
    "'Where outputs are computed')"
)


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
    late = n >= 3  # every output at row k + 1 equal to the reference at row k
    for j, name in enumerate(case.ref_columns[1:], start=1):
        y = run.data[:n, col[name]]
        y_ref = ref[:n, j]
        late = late and bool(np.all(abs(y[1:] - y_ref[:-1]) <= atol + rtol * abs(y_ref[:-1])))
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
        if late:
            notes.append(ONE_STEP_LATE.format(step=case.step))
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


def _missing(md: Any, needed: dict[str, str], causality_shown: bool = True) -> list[str]:
    """The variables of ``needed`` (name -> causality) that the FMU lacks or has with
    another causality, e.g. ``F_x (input)`` (``F_x`` if not ``causality_shown``)."""
    have = {v.name: v.causality for v in md.modelVariables}
    out = []
    for name, causality in needed.items():
        got = have.get(name)
        if got is None:
            out.append(f"{name} ({causality})" if causality_shown else name)
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
            f"FMU {quote(md.modelName)} has none of the inputs and outputs of a "
            f"component ({', '.join(COMPONENTS)}): expected e.g. the {best} interface"
        )
    return best


@dataclass
class Report:
    """The results of :func:`verify`: the FMU verified, the cases run and those skipped."""

    fmu: Path
    model_name: str
    component: str
    results: list[CaseResult] = field(default_factory=list)
    #: cases that could not run: (case, the variables it needs that the FMU lacks)
    skipped: list[tuple[str, list[str]]] = field(default_factory=list)
    sha256: str = ""
    flavor: str = ""
    fmi_version: str = ""
    #: the binary a host on this platform loads (path inside the FMU) and its SHA-256
    binary: str = ""
    binary_sha256: str = ""

    @property
    def passed(self) -> bool:
        """At least one case ran, and every case that ran passed (skipped ones never count)."""
        return bool(self.results) and all(r.passed for r in self.results)

    @property
    def exit_code(self) -> int:
        """``verify``'s exit code for this report: 0 passed, 1 a case failed."""
        return 0 if self.passed else 1

    def header(self) -> str:
        """What was verified: the FMU's file and SHA-256, model, flavor, FMI version, binary."""
        return "\n".join((
            f"FMU     {shown_path(self.fmu)} (sha256 {self.sha256})",
            f"model   {self.model_name}: {self.component}, flavor {self.flavor}, "
            f"FMI {self.fmi_version}",
            f"binary  {self.binary} (sha256 {self.binary_sha256})",
        ))  # fmt: skip

    def table(self) -> str:
        """The header, then one row per case: pass/FAIL/skipped, worst variable, max error
        vs tolerance, time; a closing count."""
        head = ("case", "result", "worst variable", "max error", "tolerance", "at t (s)",
                "run (s)", "note")  # fmt: skip
        rows = [head]
        for r in self.results:
            rows.append((
                r.case.name, "pass" if r.passed else "FAIL", r.variable or "-",
                f"{r.max_error:.3g}", f"{r.tolerance:.3g}",
                "-" if r.time is None else f"{r.time:.6g}", f"{r.seconds:.2f}", r.note,
            ))  # fmt: skip
        for name, needs in self.skipped:
            rows.append((name, "skipped", "-", "-", "-", "-", "-", f"needs {', '.join(needs)}"))
        widths = [max(len(row[i]) for row in rows) for i in range(len(head) - 1)]
        lines = [self.header(), ""]
        lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths)) + "  " + row[-1]
                  for row in rows]  # fmt: skip
        n_fail = sum(not r.passed for r in self.results)
        skipped = f"; {len(self.skipped)} skipped" if self.skipped else ""
        lines.append(
            f"{self.component} ({self.model_name}, {shown_path(self.fmu)}): "
            f"{len(self.results) - n_fail} of {len(self.results)} cases pass{skipped}"
        )
        return "\n".join(line.rstrip() for line in lines)

    def as_dict(self) -> dict[str, Any]:
        """The whole result as plain data (``verify --json``)."""
        cases: list[dict[str, Any]] = [
            {
                "case": r.case.name,
                "result": "pass" if r.passed else "fail",
                "worst_variable": r.variable,
                "max_error": _finite(r.max_error),
                "tolerance": _finite(r.tolerance),
                "rtol": r.rtol,
                "atol": r.atol,
                "time": _finite(r.time),
                "value": _finite(r.value),
                "reference": _finite(r.ref_value),
                "seconds": r.seconds,
                "note": r.note,
            }
            for r in self.results
        ]
        cases += [{"case": n, "result": "skipped", "needs": needs} for n, needs in self.skipped]
        n_pass = sum(r.passed for r in self.results)
        return {
            "fmu": str(self.fmu),
            "sha256": self.sha256,
            "model_name": self.model_name,
            "component": self.component,
            "flavor": self.flavor,
            "fmi_version": self.fmi_version,
            "binary": {"path": self.binary, "sha256": self.binary_sha256},
            "passed": self.passed,
            "exit_code": self.exit_code,
            "counts": {
                "passed": n_pass,
                "failed": len(self.results) - n_pass,
                "skipped": len(self.skipped),
            },
            "cases": cases,
        }


def _finite(value: float | None) -> float | str | None:
    """A number for JSON: non-finite ones as text (``"inf"``, ``"nan"``), which JSON lacks."""
    return value if value is None or math.isfinite(value) else str(float(value))


def _describe(path: Path, md: Any, component: str) -> Report:
    """An empty report naming what is verified (file and binary hashes, flavor, version)."""
    binary = binary_path(md)
    with zipfile.ZipFile(path) as z:
        binary_sha = hashlib.sha256(z.read(binary)).hexdigest()
    flavor, _ = zip_flavor(path, md)
    return Report(path, md.modelName, component, sha256=file_sha256(path), flavor=flavor,
                  fmi_version=md.fmiVersion, binary=binary, binary_sha256=binary_sha)  # fmt: skip


def verify(
    fmu: str | Path,
    component: str | None = None,
    case: str | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    root: Path | None = None,
    fmu_dir: str | Path | None = None,
) -> Report:
    """Run the cases of a component on ``fmu`` and compare with the references.

    An FMU with the component's core interface (:data:`~glider_cosim.verify.cases.CORE`)
    runs every case whose inputs, outputs and parameters it has; the others are listed
    in :attr:`Report.skipped` with what they need, and never count as passes.

    Parameters
    ----------
    fmu : path
        Any FMI 2.0 or 3.0 co-simulation FMU with at least the component's core
        interface (variables looked up by name in its model description).
    component : str, optional
        ``plant``, ``observer`` or ``controller``; found from the variables if omitted.
    case : str, optional
        One case (default: every case of the component).
    rtol, atol : float, optional
        Override every case's tolerances (finite, >= 0).
    root : Path, optional
        Another kit folder (default: the shipped cases).
    fmu_dir : path, optional
        Our FMUs for the closed loop of a controller's or estimator's loop checks (run
        without ``case``: :class:`~glider_cosim.verify.loop.LoopReport`).

    Raises
    ------
    VerifyInputError
        Not a usable FMU, unknown component or case, a bad tolerance, the core interface
        missing, or no case can run (what is missing named, in one line).
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
    loop = loop_checks(path, md, component, fmu_dir) if case is None else []
    missing = _missing(md, CORE[component])
    if missing and not loop:
        raise VerifyInputError(
            f"FMU {quote(path.name)} ({md.modelName}) lacks the {component} core "
            f"interface: missing {', '.join(missing)}"
        )
    report = _describe(path, md, component)
    runnable = []
    for name in names:
        needs = _missing(md, _interface(component, [name], root), causality_shown=False)
        if needs:
            report.skipped.append((name, needs))
        else:
            runnable.append(name)
    if not runnable and not loop:
        needs = "; ".join(f"{n} needs {', '.join(m)}" for n, m in report.skipped)
        raise VerifyInputError(
            f"FMU {quote(path.name)} ({md.modelName}) can run none of the "
            f"{component} cases: {needs}"
        )
    runner = RUNNERS[md.fmiVersion]
    for name in runnable:
        c = load_case(component, name, root)
        try:
            run = runner(path, md, c, c.ref_columns[1:])
        except CaseFileError:
            raise
        except ValueError as err:  # e.g. a parameter out of the FMU's declared range
            raise VerifyInputError(f"case {name}: {one_line(err)}") from None
        report.results.append(compare(c, run, rtol, atol))
    return LoopReport.of(report, loop) if loop else report
