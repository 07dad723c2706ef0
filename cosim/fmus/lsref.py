"""FMI-LS-REF in every FMU we build: the folder ``extra/org.fmi-standard.fmi-ls-ref/``
(experiments, parameter sets, the readme, the manifest listing them with checksums).

The folder's files are data in each component's folder, ``src/<component>/lsref/``
(packaged with it), written by :mod:`glider_cosim.verify.lsref_ours` (``python -m
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
from pathlib import Path

from ..components import COMPONENTS, by_model

#: the LS-REF folder in each component's folder (``src/<component>/lsref/``)
FOLDER = "lsref"
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


def shipped_folder(model: str) -> Path | None:
    """The LS-REF folder shipped for ``model`` (``lsref/`` in its component's folder,
    :mod:`glider_cosim.components`), or None for a model not registered."""
    c = by_model(model)
    return None if c is None else c.folder / FOLDER


def _model_name(md_xml: bytes) -> str:
    m = re.search(rb'\smodelName\s*=\s*"([^"]*)"', md_xml)
    return m.group(1).decode() if m else ""


def _files(model: str) -> list[Path]:
    return _files_in(shipped_folder(model))


def _files_in(folder: Path | None) -> list[Path]:
    if folder is None or not folder.is_dir():
        return []
    return sorted(p for p in folder.rglob("*") if p.is_file())


def fingerprint() -> str:
    """Hash of every component's shipped LS-REF folder: part of the FMUs' source hashes
    and of the cache's sources key (a change rebuilds the FMUs)."""
    stamp = tuple(
        (model, str(folder), str(f), f.stat().st_mtime_ns, f.stat().st_size)
        for model, folder in _shipped_folders()
        for f in _files_in(folder)
    )
    return _fingerprint(stamp)


@functools.cache
def _shipped_folders() -> tuple[tuple[str, Path], ...]:
    """(model, LS-REF folder) of every registered component (the registry is read once
    per process)."""
    return tuple((c.model, c.folder / FOLDER) for c in COMPONENTS)


@functools.lru_cache(maxsize=8)
def _fingerprint(stamp: tuple[tuple[str, str, str, int, int], ...]) -> str:
    h = hashlib.sha256()
    for model, folder, path, _, _ in stamp:
        h.update(f"{model}/{Path(path).relative_to(folder).as_posix()}".encode())
        h.update(Path(path).read_bytes())
    return h.hexdigest()


def entries(md_xml: bytes) -> dict[str, bytes]:
    """Zip path -> bytes of the LS-REF folder of the model ``md_xml`` describes (one of
    ours); empty for a model that ships none. One function for every flavor and FMI
    version."""
    model = _model_name(md_xml)
    folder = shipped_folder(model)
    return {f"{LSREF_DIR}/{p.relative_to(folder).as_posix()}": p.read_bytes()
            for p in _files(model)}  # fmt: skip


def add_to_fmu(fmu: Path) -> None:
    """Add the LS-REF folder to ``fmu`` (from its own model description; nothing for a
    model that ships none); the FMU must not carry one yet."""
    with zipfile.ZipFile(fmu, "a", zipfile.ZIP_DEFLATED) as z:
        for path, data in entries(z.read("modelDescription.xml")).items():
            z.writestr(path, data)


def is_current(z: zipfile.ZipFile) -> bool:
    """True if the FMU open in ``z`` carries the LS-REF manifest shipped for its model
    now (always true for a model that ships none)."""
    folder = shipped_folder(_model_name(z.read("modelDescription.xml")))
    shipped = folder / "fmi-ls-manifest.xml" if folder is not None else None
    if shipped is None or not shipped.is_file():
        return True
    want = shipped.read_bytes()
    try:
        return z.read(MANIFEST) == want
    except KeyError:
        return False
