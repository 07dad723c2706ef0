"""FMI-LS-REF in every FMU we build: the folder ``extra/org.fmi-standard.fmi-ls-ref/``
(experiments, parameter sets, the readme, the manifest listing them with checksums).

The folder's files are data shipped in the package, ``verification/lsref/<model>/``,
written by :mod:`glider_cosim.verify.lsref_ours` (``python -m
glider_cosim.verify.lsref_ours --write``); what they hold and what the standards leave
open is told in :mod:`glider_cosim.interop.lsref_write`. Every build (both flavors,
FMI 2.0 and 3.0) packs them through :func:`entries`; the FMUs' binaries and model
descriptions do not change.
"""

from __future__ import annotations

import functools
import hashlib
import re
import zipfile
from importlib import resources
from pathlib import Path

#: the folder of the layered standard in an FMU
LSREF_DIR = "extra/org.fmi-standard.fmi-ls-ref"
#: the manifest (the standard's fixed name)
MANIFEST = f"{LSREF_DIR}/fmi-ls-manifest.xml"
#: the annotation of a ``<Related>`` carrying its file's checksum, and its element's
#: namespace (the standard's ``<Related>`` has no checksum attribute)
CHECKSUM_TYPE = "org.glider-cosim.checksum"
CHECKSUM_NS = "urn:glider-cosim:checksum"
#: the checksum written (Python's ``hashlib.sha3_256``)
CHECKSUM_ALGORITHM = "SHA3-256"
#: the MIME type of an experiments file (MA-HS-Experiments)
EXPERIMENTS_MIME = "application/x-ma-hs-experiments"
#: the roles of an experiment (``glider-cosim add-experiments --role``)
ROLES = ("experiment", "experiment/smoke-test", "experiment/validation")
#: the tolerance of an experiment that gives none
DEFAULT_TOLERANCE = 1e-6


def sha3(data: bytes) -> str:
    """The SHA3-256 of ``data`` (hex), the checksum of every entry."""
    return hashlib.sha3_256(data).hexdigest()


def data_root() -> Path:
    """The shipped LS-REF folders, one per model (in the installed package)."""
    return Path(str(resources.files("glider_cosim") / "verification" / "lsref"))


def _model_name(md_xml: bytes) -> str:
    m = re.search(rb'\smodelName\s*=\s*"([^"]*)"', md_xml)
    return m.group(1).decode() if m else ""


def _files(model: str) -> list[Path]:
    folder = data_root() / model
    return sorted(p for p in folder.rglob("*") if p.is_file()) if folder.is_dir() else []


def fingerprint() -> str:
    """Hash of the shipped LS-REF folders: part of the FMUs' source hashes and of the
    cache's sources key (a change rebuilds the FMUs)."""
    root = data_root()
    files = sorted(p for p in root.rglob("*") if p.is_file()) if root.is_dir() else []
    stamp = tuple((str(f), f.stat().st_mtime_ns, f.stat().st_size) for f in files)
    return _fingerprint(stamp)


@functools.lru_cache(maxsize=8)
def _fingerprint(stamp: tuple[tuple[str, int, int], ...]) -> str:
    h = hashlib.sha256()
    root = data_root()
    for path, _, _ in stamp:
        h.update(Path(path).relative_to(root).as_posix().encode())
        h.update(Path(path).read_bytes())
    return h.hexdigest()


def entries(md_xml: bytes) -> dict[str, bytes]:
    """Zip path -> bytes of the LS-REF folder of the model ``md_xml`` describes (one of
    ours); empty for a model that ships none. One function for every flavor and FMI
    version."""
    folder = data_root() / _model_name(md_xml)
    return {f"{LSREF_DIR}/{p.relative_to(folder).as_posix()}": p.read_bytes()
            for p in _files(folder.name)}  # fmt: skip


def add_to_fmu(fmu: Path) -> None:
    """Add the LS-REF folder to ``fmu`` (from its own model description; nothing for a
    model that ships none); the FMU must not carry one yet."""
    with zipfile.ZipFile(fmu, "a", zipfile.ZIP_DEFLATED) as z:
        for path, data in entries(z.read("modelDescription.xml")).items():
            z.writestr(path, data)


def is_current(z: zipfile.ZipFile) -> bool:
    """True if the FMU open in ``z`` carries the LS-REF manifest shipped for its model
    now (always true for a model that ships none)."""
    shipped = data_root() / _model_name(z.read("modelDescription.xml")) / "fmi-ls-manifest.xml"
    if not shipped.is_file():
        return True
    want = shipped.read_bytes()
    try:
        return z.read(MANIFEST) == want
    except KeyError:
        return False
