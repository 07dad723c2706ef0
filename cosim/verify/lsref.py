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
from dataclasses import dataclass
from pathlib import Path
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
from ..inputs.text import one_line, quote
from .cases import VerifyInputError
from .lsref_report import LsrefFileError, LsrefReport, Planned, compare
from .lsref_run import simulate


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


def lsref_command(fmu: str, as_json: bool) -> int | None:
    """``glider-cosim verify FMU`` on the experiments the FMU carries: print the report
    (``as_json``: one JSON object), return the exit code; None if it carries none and is
    one of our components (then the kit's cases run). An FMU that carries none and is no
    component of ours is refused in one line (:class:`VerifyInputError`)."""
    import json

    report = verify_lsref(fmu)
    if report is None:
        from .compare import detect_component
        from .run import open_fmu

        md = open_fmu(Path(fmu))
        try:
            detect_component(md)
        except VerifyInputError:
            raise VerifyInputError(
                f"FMU {quote(Path(fmu).name)} ({md.modelName}) carries no FMI-LS-REF "
                f"experiments ({MANIFEST}) and is not a glider component: nothing to verify"
            ) from None
        return None
    print(json.dumps(report.as_dict(), indent=1) if as_json else report.table())
    return report.exit_code
