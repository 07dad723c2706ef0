"""Running the FMI-LS-REF experiments an FMU carries (``glider-cosim verify``), ours or
anyone's.

The FMU's ``extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml`` lists its related
files; every entry with the role ``experiment`` (or ``experiment/<sub-role>``) and the
type ``application/x-ma-hs-experiments`` is read, and each of its transient experiments
is run with fmpy (``FMU2Slave``/``FMU3Slave``): the parameters of its SSV set before
initialisation, its stimuli held from each row's time to the next at the communication
points ``start + k * step``, the outputs read after the inputs of each point are set and
compared with its references at its tolerance: ``|y - y_ref| <= tol * (1 + |y_ref|)``
(:mod:`glider_cosim.fmus.lsref` says what the standards leave open and what we chose).

Every entry with a checksum (our annotation :data:`~glider_cosim.fmus.lsref.CHECKSUM_TYPE`)
is checked first: a file that does not match is a failure that names the file, "changed
after the FMU was built".
"""

from __future__ import annotations

import math
import posixpath
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np

from ..fmus.lsref import (
    CHECKSUM_NS,
    CHECKSUM_TYPE,
    DEFAULT_TOLERANCE,
    EXPERIMENTS_MIME,
    LSREF_DIR,
    MANIFEST,
    sha3,
)
from ..inputs.text import one_line, quote, shown_path
from .cases import VerifyInputError


class LsrefFileError(VerifyInputError):
    """A file of the FMU's LS-REF folder cannot be used (names the file and what is wrong)."""


@dataclass
class Entry:
    """One ``<Related>`` of the manifest."""

    source: str
    role: str
    type: str
    description: str
    checksum: str | None
    algorithm: str | None

    @property
    def path(self) -> str:
        """The entry's path in the FMU archive."""
        return resolve(LSREF_DIR, self.source, MANIFEST)


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


# ------------------------------------------------------------------ reading
def resolve(folder: str, source: str, where: str) -> str:
    """A relative URI of an LS-REF file as a path in the archive (from ``folder``); an
    absolute URI or a path leaving the archive is refused."""
    if "://" in source or source.startswith(("/", "\\")) or ":" in source.split("/")[0]:
        raise LsrefFileError(
            f"{where}: source {quote(source)} is not a relative path in the FMU "
            "(other URIs are not supported)"
        )
    path = posixpath.normpath(posixpath.join(folder, source))
    if path.startswith("../") or path == "..":
        raise LsrefFileError(f"{where}: source {quote(source)} leaves the FMU archive")
    return path


def _parse(data: bytes, where: str) -> ET.Element:
    try:
        return ET.fromstring(data)
    except ET.ParseError as err:
        raise LsrefFileError(f"{where}: not valid XML ({err})") from None


def read_manifest(z: zipfile.ZipFile) -> list[Entry] | None:
    """The manifest's entries; None if the FMU carries no manifest."""
    try:
        data = z.read(MANIFEST)
    except KeyError:
        return None
    root = _parse(data, MANIFEST)
    if root.tag != "fmiReferences":
        raise LsrefFileError(f"{MANIFEST}: the root is <{root.tag}>, expected <fmiReferences>")
    out = []
    for el in root.findall("Related"):
        source, role = el.get("source"), el.get("role")
        if not source or not role:
            raise LsrefFileError(f"{MANIFEST}: a <Related> without source or role")
        checksum = algorithm = None
        for note in el.findall("Annotations/Annotation"):
            if note.get("type") == CHECKSUM_TYPE:
                c = note.find(f"{{{CHECKSUM_NS}}}Checksum")
                if c is not None:
                    checksum, algorithm = c.get("value"), c.get("algorithm", "SHA3-256")
        out.append(
            Entry(
                source,
                role,
                el.get("type", "application/octet-stream"),
                el.get("description", ""),
                checksum,
                algorithm,
            )
        )
    return out


def check_checksums(z: zipfile.ZipFile, entries: list[Entry]) -> list[tuple[str, str]]:
    """(path, "ok" or what is wrong) of every entry with a checksum."""
    out = []
    for e in entries:
        if e.checksum is None:
            continue
        path = e.path
        try:
            data = z.read(path)
        except KeyError:
            out.append((path, "missing: listed in the manifest with a checksum, not in the FMU"))
            continue
        if (e.algorithm or "").upper() != "SHA3-256":
            out.append(
                (path, f"checksum type {quote(e.algorithm)} is not supported (expected SHA3-256)")
            )
        elif sha3(data) != e.checksum.strip().lower():
            out.append(
                (
                    path,
                    f"SHA3-256 {sha3(data)[:16]}... does not match the manifest's "
                    f"{e.checksum[:16]}...: changed after the FMU was built",
                )
            )
        else:
            out.append((path, "ok"))
    return out


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


def _table(z: zipfile.ZipFile, path: str, where: str) -> tuple[list[str], np.ndarray]:
    """A CSV of the FMU (``time`` first) as (columns, rows)."""
    import csv
    import io

    try:
        text = z.read(path).decode("utf-8-sig")
    except KeyError:
        raise LsrefFileError(f"{where}: {path} is not in the FMU") from None
    except UnicodeDecodeError:
        raise LsrefFileError(f"{path}: not UTF-8 text") from None
    rows = [r for r in csv.reader(io.StringIO(text)) if r]
    if not rows or rows[0][0].strip() != "time":
        raise LsrefFileError(f"{path}: expected a header starting with 'time'")
    cols = [c.strip() for c in rows[0]]
    try:
        data = np.array([[float(v) for v in r] for r in rows[1:]], dtype=float)
    except ValueError as err:
        raise LsrefFileError(f"{path}: {one_line(err)}") from None
    if data.ndim != 2 or len(data) < 1 or data.shape[1] != len(cols):
        raise LsrefFileError(f"{path}: every row needs {len(cols)} numbers")
    if not np.all(np.isfinite(data)) or np.any(np.diff(data[:, 0]) <= 0):
        raise LsrefFileError(f"{path}: values must be finite, times increasing")
    return cols, data


def _ssv(z: zipfile.ZipFile, path: str, where: str) -> dict[str, tuple[str, str]]:
    from ..interop.ssp_common import NS, as_ssp1_type, local_name

    try:
        root = _parse(z.read(path), path)
    except KeyError:
        raise LsrefFileError(f"{where}: {path} is not in the FMU") from None
    if local_name(root.tag) != "ParameterSet":
        raise LsrefFileError(f"{path}: the root is not an ssv:ParameterSet")
    out = {}
    for p in root.iterfind("ssv:Parameters/ssv:Parameter", NS):
        typed = [t for t in p if local_name(t.tag) != "Annotations"]
        if not typed or typed[0].get("value") is None:
            raise LsrefFileError(f"{path}: parameter {quote(p.get('name'))} has no value")
        out[p.get("name", "")] = (as_ssp1_type(local_name(typed[0].tag)), typed[0].get("value"))
    return out


def _number(el: ET.Element, key: str, where: str, default: float | None = None) -> float:
    text = el.get(key)
    try:
        value = float(text) if text is not None else default
    except ValueError:
        value = None
    if value is None or not math.isfinite(value):
        raise LsrefFileError(f"{where}: {key} {quote(text)} is invalid: expected a finite number")
    return value


def _source(ex: ET.Element, tag: str, folder: str, where: str) -> str | None:
    """The archive path of an experiment's ``<Parameters>``/``<Stimuli>``/``<References>``
    (relative to the experiments file's folder), None if it has none."""
    el = ex.find(tag)
    if el is None:
        return None
    if not el.get("source"):
        raise LsrefFileError(f"{where}: <{tag}> without source")
    return resolve(folder, el.get("source"), where)


def read_experiments(z: zipfile.ZipFile, entry: Entry) -> list[Planned]:
    """Every experiment of an experiments file of the FMU."""
    path = entry.path
    try:
        root = _parse(z.read(path), path)
    except KeyError:
        raise LsrefFileError(f"{MANIFEST}: experiment file {path} is not in the FMU") from None
    if root.tag != "Experiments":
        raise LsrefFileError(f"{path}: the root is <{root.tag}>, expected <Experiments>")
    folder = posixpath.dirname(path)
    out = []
    for ex in root.findall("Experiment"):
        name = ex.get("name") or "?"
        where = f"{path}: experiment {quote(name)}"
        ts = ex.find("TransientSimulation")
        if ts is None:  # older drafts put the times on <Experiment>
            ts = ex if ex.get("stopTime") is not None else None
        if ts is None:
            raise LsrefFileError(
                f"{where}: only transient experiments (<TransientSimulation>) can be run"
            )
        start = _number(ts, "startTime", where, 0.0)
        stop = _number(ts, "stopTime", where)
        step = _number(ts, "stepSize", where)
        tol = _number(ex, "tolerance", where, DEFAULT_TOLERANCE)
        if not (stop > start and step > 0 and tol >= 0):
            raise LsrefFileError(
                f"{where}: expected stopTime > startTime, stepSize > 0, tolerance >= 0"
            )

        par, stim, ref = (
            _source(ex, tag, folder, where) for tag in ("Parameters", "Stimuli", "References")
        )
        out.append(
            Planned(
                posixpath.relpath(path, LSREF_DIR),
                entry.role,
                name,
                tol,
                start,
                stop,
                step,
                _ssv(z, par, where) if par else {},
                _table(z, stim, where) if stim else None,
                _table(z, ref, where) if ref else None,
            )
        )
    if not out:
        raise LsrefFileError(f"{path}: no <Experiment>")
    return out


# ------------------------------------------------------------------ running (fmpy)
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
        "unzipDirectory": unzipdir,
        "modelIdentifier": md.coSimulation.modelIdentifier,
        "instanceName": "lsref",
    }
    slave = (
        FMU3Slave(instantiationToken=md.instantiationToken, **common)
        if fmi3
        else FMU2Slave(guid=md.guid, **common)
    )

    def put(name: str, value: Any) -> None:
        v = variables[name]
        getattr(slave, _SETTERS[v.type])([v.valueReference], [value])

    n = int(round((ex.stop - ex.start) / ex.step))
    rows: list[list[float]] = []
    note = ""
    stim_t = ex.stimuli[1][:, 0] if ex.stimuli else None
    slave.instantiate()
    try:
        if not fmi3:
            slave.setupExperiment(startTime=ex.start)
        for name, (_, text) in ex.parameters.items():
            put(name, _typed(variables[name], text, f"{where}: parameter {quote(name)}"))
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

        if fmi3:
            slave.enterInitializationMode(startTime=ex.start)
        else:
            slave.enterInitializationMode()
        drive(ex.start)  # the inputs at the start take part in the initialisation
        slave.exitInitializationMode()
        vrs = [variables[c].valueReference for c in ref_cols]
        kinds = [variables[c].type for c in ref_cols]
        for k in range(n + 1):
            t = ex.start + k * ex.step
            drive(t)
            row = [t]
            for vr, kind in zip(vrs, kinds):
                row.append(float(getattr(slave, _GETTERS[kind])([vr])[0]))
            rows.append(row)
            if k == n:
                break
            try:
                slave.doStep(t, ex.step)
            except Exception as err:  # noqa: BLE001 - fmpy raises FMICallException
                note = f"the FMU stopped at t = {t:g} s: {one_line(err)}"
                break
        slave.terminate()
    finally:
        try:
            slave.freeInstance()
        except Exception:  # noqa: BLE001 - an FMU that failed may refuse that too
            pass
    return np.array(rows, dtype=float).reshape(-1, 1 + len(ref_cols)), note


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


def carries_lsref(fmu: str | Path) -> bool:
    """True if ``fmu`` (a zip) carries an LS-REF manifest."""
    try:
        with zipfile.ZipFile(fmu) as z:
            return MANIFEST in z.namelist()
    except (OSError, zipfile.BadZipFile):
        return False


def verify_lsref(fmu: str | Path) -> LsrefReport | None:
    """Check the checksums and run every LS-REF experiment ``fmu`` carries.

    Parameters
    ----------
    fmu : path
        Any FMI 2.0 or 3.0 co-simulation FMU.

    Returns
    -------
    LsrefReport or None
        None if the FMU carries no LS-REF manifest, or none of its entries is an
        experiment file (nothing to run; checksums alone are not a verification).

    Raises
    ------
    VerifyInputError
        Not a usable FMU, or an LS-REF file cannot be read (:class:`LsrefFileError`,
        one line naming the file).
    """
    import fmpy

    from ..runner.provenance import file_sha256
    from .run import open_fmu

    path = Path(fmu)
    md = open_fmu(path)
    with zipfile.ZipFile(path) as z:
        entries = read_manifest(z)
        if entries is None:
            return None
        experiment_files = [
            e
            for e in entries
            if e.role.split("/")[0] == "experiment"
            and e.type in (EXPERIMENTS_MIME, "application/x-ma-ls-experiments")
        ]
        if not experiment_files:
            return None
        report = LsrefReport(path, md.modelName, md.fmiVersion, file_sha256(path))
        report.checksums = check_checksums(z, entries)
        planned = [ex for e in experiment_files for ex in read_experiments(z, e)]
    if md.coSimulation is None:
        raise VerifyInputError(
            f"FMU {quote(path.name)} is not a co-simulation FMU: its experiments cannot be run"
        )
    unzipdir = fmpy.extract(str(path))
    try:
        for ex in planned:
            t0 = time.perf_counter()
            data, note = simulate(path, md, unzipdir, ex)
            report.experiments.append(compare(ex, data, note, time.perf_counter() - t0))
    finally:
        import shutil

        shutil.rmtree(unzipdir, ignore_errors=True)
    return report
