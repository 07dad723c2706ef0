"""The report of :func:`glider_cosim.verify.lsref.verify_lsref`: per experiment and per
variable, and the comparison that makes it: a value passes if
``|y - y_ref| <= tol * (1 + |y_ref|)`` at each reference row (``tol``: the experiment's
tolerance)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..inputs.text import quote, shown_path
from .cases import VerifyInputError


class LsrefFileError(VerifyInputError):
    """A file of the FMU's LS-REF folder cannot be used (names the file and what is wrong)."""


@dataclass
class Planned:
    """One experiment as read from its file (data, not yet run)."""

    file: str
    role: str
    name: str
    tolerance: float
    start: float
    stop: float
    step: float
    parameters: dict[str, tuple[str, str]]  # name -> (SSV type, value text)
    stimuli: tuple[list[str], np.ndarray] | None
    references: tuple[list[str], np.ndarray] | None


@dataclass
class VariableResult:
    """One variable of an experiment: its worst point against the tolerance there."""

    name: str
    passed: bool
    max_error: float
    tolerance: float
    time: float | None
    value: float | None
    reference: float | None


@dataclass
class ExperimentResult:
    """One experiment of an experiments file: pass/fail, per variable, and a note."""

    file: str
    role: str
    name: str
    tolerance: float
    start: float
    stop: float
    step: float
    passed: bool
    variables: list[VariableResult] = field(default_factory=list)
    note: str = ""
    seconds: float = 0.0


@dataclass
class LsrefReport:
    """What :func:`verify_lsref` found: checksums and experiments."""

    fmu: Path
    model_name: str
    fmi_version: str
    sha256: str
    #: (file in the archive, "ok" or what is wrong)
    checksums: list[tuple[str, str]] = field(default_factory=list)
    experiments: list[ExperimentResult] = field(default_factory=list)

    @property
    def checksum_failures(self) -> list[tuple[str, str]]:
        return [(f, m) for f, m in self.checksums if m != "ok"]

    @property
    def passed(self) -> bool:
        """Every checksum matches, at least one experiment ran and every one passed."""
        return (
            not self.checksum_failures
            and bool(self.experiments)
            and all(e.passed for e in self.experiments)
        )

    @property
    def exit_code(self) -> int:
        return 0 if self.passed else 1

    def table(self) -> str:
        """The FMU, the checksums' failures, one block per experiment (one row per
        variable), a closing count."""
        lines = [
            f"FMU     {shown_path(self.fmu)} (sha256 {self.sha256})",
            f"model   {self.model_name}: FMI {self.fmi_version}, FMI-LS-REF "
            f"({len(self.experiments)} experiments, {len(self.checksums)} checksums)",
        ]
        for path, message in self.checksum_failures:
            lines.append(f"checksum FAIL  {path}: {message}")
        for e in self.experiments:
            verdict = "pass" if e.passed else "FAIL"
            lines += [
                "",
                f"{e.file} [{e.role}] experiment {e.name!r}: {verdict} (tolerance "
                f"{e.tolerance:g}, {e.start:g} to {e.stop:g} s, step {e.step:g} s, "
                f"run {e.seconds:.2f} s){'; ' + e.note if e.note else ''}",
            ]
            if e.variables:
                rows = [
                    (
                        "variable",
                        "result",
                        "max error",
                        "tolerance",
                        "at t (s)",
                        "value",
                        "reference",
                    )
                ]
                for v in e.variables:
                    rows.append(
                        (
                            v.name,
                            "pass" if v.passed else "FAIL",
                            f"{v.max_error:.3g}",
                            f"{v.tolerance:.3g}",
                            _num(v.time, "{:.6g}"),
                            _num(v.value, "{:.10g}"),
                            _num(v.reference, "{:.10g}"),
                        )
                    )
                widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
                lines += [
                    "  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows
                ]
        n_pass = sum(e.passed for e in self.experiments)
        bad = len(self.checksum_failures)
        lines += [
            "",
            f"{self.model_name} ({shown_path(self.fmu)}): {n_pass} of "
            f"{len(self.experiments)} experiments pass"
            + (f"; {bad} file(s) changed after the FMU was built" if bad else ""),
        ]
        return "\n".join(lines)

    def as_dict(self) -> dict[str, Any]:
        """The whole result as plain data (``verify --json``)."""
        n_pass = sum(e.passed for e in self.experiments)
        return {
            "fmu": str(self.fmu),
            "sha256": self.sha256,
            "model_name": self.model_name,
            "fmi_version": self.fmi_version,
            "kind": "fmi-ls-ref",
            "passed": self.passed,
            "exit_code": self.exit_code,
            "counts": {
                "passed": n_pass,
                "failed": len(self.experiments) - n_pass,
                "checksum_failures": len(self.checksum_failures),
            },
            "checksums": [
                {
                    "file": f,
                    "result": "pass" if m == "ok" else "fail",
                    **({} if m == "ok" else {"message": m}),
                }
                for f, m in self.checksums
            ],
            "experiments": [
                {
                    "file": e.file,
                    "role": e.role,
                    "experiment": e.name,
                    "result": "pass" if e.passed else "fail",
                    "tolerance": e.tolerance,
                    "start": e.start,
                    "stop": e.stop,
                    "step": e.step,
                    "seconds": e.seconds,
                    "note": e.note,
                    "variables": [
                        {
                            "name": v.name,
                            "result": "pass" if v.passed else "fail",
                            "max_error": _finite(v.max_error),
                            "tolerance": _finite(v.tolerance),
                            "time": _finite(v.time),
                            "value": _finite(v.value),
                            "reference": _finite(v.reference),
                        }
                        for v in e.variables
                    ],
                }
                for e in self.experiments
            ],
        }


def _num(v: float | None, fmt: str) -> str:
    return "-" if v is None else fmt.format(v)


def _finite(value: float | None) -> float | str | None:
    return value if value is None or math.isfinite(value) else str(float(value))


def compare(ex: Planned, data: np.ndarray, note: str, seconds: float) -> ExperimentResult:
    """Compare a run with the experiment's references, per variable."""
    res = ExperimentResult(
        ex.file,
        ex.role,
        ex.name,
        ex.tolerance,
        ex.start,
        ex.stop,
        ex.step,
        True,
        note=note,
        seconds=seconds,
    )
    if note:
        res.passed = False
    if ex.references is None:
        res.note = "; ".join(filter(None, [note, "no references: the run itself is the test"]))
        return res
    cols, ref = ex.references
    k = np.round((ref[:, 0] - ex.start) / ex.step)
    off = np.abs(ex.start + k * ex.step - ref[:, 0]) > 1e-6 * ex.step
    if np.any(off) or np.any(k < 0) or np.any(k > round((ex.stop - ex.start) / ex.step)):
        bad = ref[np.argmax(off | (k < 0)), 0]
        raise LsrefFileError(
            f"{ex.file}: experiment {quote(ex.name)}: reference time {bad:g} s "
            "is not a communication point between start and stop"
        )
    k = k.astype(int)
    reached = k < len(data)
    if not np.all(reached):
        res.passed = False
    for j, name in enumerate(cols[1:], start=1):
        y_ref = ref[reached, j]
        y = data[k[reached], j]
        err = np.abs(y - y_ref)
        err = np.where(np.isfinite(err), err, np.inf)
        tol = ex.tolerance * (1.0 + np.abs(y_ref))
        if not len(err):
            res.variables.append(VariableResult(name, False, math.inf, 0.0, None, None, None))
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(tol > 0, err / tol, np.where(err > 0, np.inf, 0.0))
        i = int(np.argmax(ratio))
        ok = bool(np.all(err <= tol))
        res.passed &= ok
        res.variables.append(
            VariableResult(
                name,
                ok,
                float(err[i]),
                float(tol[i]),
                float(ref[reached][i, 0]),
                float(y[i]),
                float(y_ref[i]),
            )
        )
    return res
