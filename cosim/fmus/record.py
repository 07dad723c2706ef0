"""The record an FMU folder keeps of what glider-cosim built there, and the check made
before anything is built there: nothing of the user's is written over.

Every build into a folder (``glider-cosim build``, ``--fmu-dir`` of ``run``, ``sweep``,
``report``, the exports, ``verify --write-references/--export``) writes
``.glider-cosim-fmus.json`` (:data:`RECORD_FILE`) beside the FMUs: for each file it
wrote (the three ``.fmu`` files and their ``<id>_OspModelDescription.xml``), its
SHA-256 and, for an FMU, its flavor, FMI version, source hash (the hash a rebuild
compares, also inside the FMU) and, for a native one, its platforms.

Before a build, each file under one of our names is judged (:func:`survey`):

- *ours*: the record lists it with its SHA-256; in a folder without a record (one
  written before the record existed), an FMU that carries the provenance every FMU of
  ours carries (its flavor and source hash in ``resources/``), and an OSP-IS description
  (``<id>_OspModelDescription.xml``, its root element) under one of our names;
- *foreign*: not in the record (a user's own ``GliderController.fmu``, a copy from
  elsewhere) or, without a record, no provenance;
- *changed*: the record lists it with another SHA-256 (edited, repacked, truncated);
- *corrupt*: not a zip archive with a ``modelDescription.xml``, and not ours.

A foreign, changed or corrupt file is refused (:class:`FmuFolderError`, one line naming
the file and how to go on) unless ``overwrite`` (``--overwrite-fmus``); so is a set of
ours of another flavor or FMI version than the one asked for (it is never converted in
place). The per-user cache is glider-cosim's own: there such a file is replaced, with a
warning.

Builds into one folder are serialised by a lock (filelock, on every platform; its file
is the cache's: :func:`lock_file`), so that two processes never leave a record that
disagrees with the files.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import zipfile
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import filelock

from ..inputs.text import quote
from .files import FLAVOR_FILE, cache_root, file_sha256, package_version, replacing
from .fmi3 import FMI3_HASH_FILE
from .native import NATIVE_HASH_FILE, PLATFORMS_FILE
from .osp import NS as OSP_NS
from .osp import SUFFIX as OSP_SUFFIX
from .python import HASH_FILE

log = logging.getLogger(__name__)

#: the record's file name, in the FMU folder
RECORD_FILE = ".glider-cosim-fmus.json"
#: the record's format version
RECORD_FORMAT = 1
#: the CLI flag that lets a build replace what the check refuses
OVERWRITE_FLAG = "--overwrite-fmus"
#: the resources holding the hash an FMU was built from, by flavor and FMI version
HASH_FILES = {
    ("python", 2): HASH_FILE,
    ("python", 3): FMI3_HASH_FILE,
    ("native", 2): NATIVE_HASH_FILE,
    ("native", 3): NATIVE_HASH_FILE,
}


class FmuFolderError(ValueError):
    """An FMU folder holds, under one of our FMUs' names, a file glider-cosim did not
    write there (or that changed since), or a set of another flavor or FMI version."""


@dataclass(frozen=True)
class Held:
    """What a folder holds under one of our file names.

    ``state``: ``"missing"``, ``"ours"``, ``"foreign"``, ``"changed"`` or ``"corrupt"``;
    ``flavor`` and ``fmi``: an FMU's (None if unknown); ``sha256``: the file's (None if
    missing)."""

    name: str
    state: str
    flavor: str | None = None
    fmi: int | None = None
    sha256: str | None = None


def provenance(fmu: Path) -> dict[str, Any] | None:
    """What an FMU of ours records of itself: ``flavor``, ``fmi``, ``source_hash`` (and
    ``platforms`` for a native one); None if it records no flavor and source hash (not
    ours) or is unreadable."""
    import re

    try:
        with zipfile.ZipFile(fmu) as z:
            head = z.read("modelDescription.xml")[:4096].decode("utf-8", "replace")
            found = re.search(r'fmiVersion\s*=\s*"([23])\.', head)
            fmi = int(found.group(1)) if found else None
            flavor = z.read(FLAVOR_FILE).decode().strip()
            source = z.read(HASH_FILES[(flavor, fmi)]).decode().strip()
            info: dict[str, Any] = {"flavor": flavor, "fmi": fmi, "source_hash": source}
            if flavor == "native":
                info["platforms"] = z.read(PLATFORMS_FILE).decode().split()
            return info
    except (OSError, KeyError, ValueError, zipfile.BadZipFile):
        return None


def readable(fmu: Path) -> bool:
    """True if ``fmu`` is a zip archive with a ``modelDescription.xml``."""
    try:
        with zipfile.ZipFile(fmu) as z:
            z.getinfo("modelDescription.xml")
        return True
    except (OSError, KeyError, zipfile.BadZipFile):
        return False


def read_record(folder: Path, option: str = "--fmu-dir") -> dict[str, dict] | None:
    """The record of ``folder``: file name -> entry; None if it has none. A record that
    cannot be read is refused (:class:`FmuFolderError`)."""
    path = folder / RECORD_FILE
    if not path.exists():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        files = data["files"]
        if not isinstance(files, dict) or not all(
            isinstance(e, dict) and isinstance(e.get("sha256"), str) for e in files.values()
        ):
            raise ValueError("not a table of files with their sha256")
        return files
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as err:
        reason = err.strerror if isinstance(err, OSError) and err.strerror else "not valid"
        raise FmuFolderError(
            f"{option} {quote(str(folder))}: {RECORD_FILE}, glider-cosim's record of the FMUs "
            f"it built there, is unreadable ({reason}): use another folder, or pass "
            f"{OVERWRITE_FLAG} to rebuild our FMUs there and write a new record"
        ) from None


def osp_name(fmu_name: str) -> str:
    """The OSP-IS description written beside the FMU ``fmu_name`` (``X.fmu``)."""
    return fmu_name.removesuffix(".fmu") + OSP_SUFFIX


def survey(folder: Path, fmu_names: Iterable[str], record: Mapping[str, dict] | None) -> dict:
    """What ``folder`` holds under each of ``fmu_names`` and the OSP-IS description
    beside each: file name -> :class:`Held` (see the module's rules)."""
    held: dict[str, Held] = {}
    for name in fmu_names:
        fmu = folder / name
        held[name] = _judge(fmu, record, lambda fmu=fmu: provenance(fmu))
        beside = folder / osp_name(name)
        ours = held[name].state == "ours"
        held[beside.name] = _judge(
            beside, record, lambda p=beside, ours=ours: {} if ours or osp_description(p) else None
        )
    return held


def osp_description(path: Path) -> bool:
    """True if ``path`` is an OSP-IS model description (its root element), as every build
    writes beside an FMU: in a folder without a record, one under our names is ours."""
    from xml.etree import ElementTree as ET

    try:
        if path.stat().st_size > 1 << 20:
            return False
        root = ET.fromstring(path.read_bytes())
    except (OSError, ET.ParseError):
        return False
    return root.tag == f"{{{OSP_NS}}}OspModelDescription"


def _judge(path: Path, record: Mapping[str, dict] | None, legacy) -> Held:
    """One file's :class:`Held`; ``legacy()``: its provenance (a dict) when the folder has
    no record, None if it carries none."""
    if not path.exists() and not path.is_symlink():
        return Held(path.name, "missing")
    if not path.is_file():
        return Held(path.name, "corrupt")
    sha = file_sha256(path)
    fmu = path.suffix == ".fmu"
    if record is None:
        info = legacy()
        if info is not None:
            return Held(path.name, "ours", info.get("flavor"), info.get("fmi"), sha)
    else:
        entry = record.get(path.name)
        if entry is not None and entry.get("sha256") == sha:
            return Held(path.name, "ours", entry.get("flavor"), entry.get("fmi"), sha)
        if entry is not None:
            return Held(path.name, "changed", sha256=sha)
    if fmu and not readable(path):
        return Held(path.name, "corrupt", sha256=sha)
    return Held(path.name, "foreign", sha256=sha)


def refusal(folder: Path, held: Held, option: str = "--fmu-dir") -> str:
    """The one line that refuses to write over ``held`` in ``folder``."""
    where = f"{option} {quote(str(folder))}"
    what = {
        "foreign": f"{held.name} was not built there by glider-cosim (not in its record "
        f"{RECORD_FILE})",
        "changed": f"{held.name} changed since glider-cosim built it (its SHA-256 is not the "
        f"one in {RECORD_FILE}"
        + (
            "; it is no longer a readable FMU)"
            if held.name.endswith(".fmu") and not readable(folder / held.name)
            else ")"
        ),
        "corrupt": f"{held.name} is not a readable FMU (not a zip archive with a "
        "modelDescription.xml) and glider-cosim did not build it there",
    }[held.state]
    ways = ["use another folder", f"pass {OVERWRITE_FLAG} to replace it with ours"]
    if held.state != "corrupt" and option == "--fmu-dir" and readable(folder / held.name):
        ways.append("name it in a scenario's [fmus] table to run it")
    return f"{where}: {what}: it is not written over; {', '.join(ways[:-1])} or {ways[-1]}"


def describe_set(flavor: str | None, fmi: int | None) -> str:
    """``FMI 2.0 python`` (the parts known)."""
    parts = ([f"FMI {fmi}.0"] if fmi else []) + ([flavor] if flavor else [])
    return " ".join(parts) or "unknown"


def entry_for(path: Path) -> dict[str, Any]:
    """The record's entry of a file just written (an FMU's provenance with it)."""
    entry: dict[str, Any] = {"sha256": file_sha256(path)}
    if path.suffix == ".fmu":
        entry.update(provenance(path) or {})
    return entry


def write_record(folder: Path, files: Mapping[str, dict]) -> Path:
    """Write the record of ``folder`` (file name -> entry), in one step."""
    data = {
        "about": "the files glider-cosim built in this folder; it writes over only these, "
        "while their SHA-256 is the one here",
        "format": RECORD_FORMAT,
        "glider_cosim": package_version(),
        "files": {k: files[k] for k in sorted(files)},
    }
    path = folder / RECORD_FILE
    with replacing(path) as part:
        part.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    return path


def lock_file(folder: Path) -> Path:
    """The lock of builds into ``folder``: a file of the cache's (``<cache>/<version>/locks``,
    named by the folder's absolute path's hash), so that nothing is written into the
    folder before a build is allowed there."""
    key = hashlib.sha256(str(Path(folder).resolve()).encode()).hexdigest()[:16]
    return cache_root() / package_version() / "locks" / f"{key}.lock"


@contextlib.contextmanager
def locked(folder: Path) -> Iterator[None]:
    """Hold the lock of ``folder`` (created if missing; :func:`lock_file`) for the block:
    builds into one folder run one at a time, on every platform (filelock). Where the
    lock cannot be taken (a cache that cannot be written, a file system without locks)
    the build goes on unlocked."""
    folder.mkdir(parents=True, exist_ok=True)
    path = lock_file(folder)
    lock = filelock.FileLock(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        try:
            lock.acquire(timeout=0)
        except filelock.Timeout:
            log.warning(f"{quote(str(folder))}: another glider-cosim is building FMUs there: "
                        "waiting for it")  # fmt: skip
            lock.acquire()
    except (OSError, NotImplementedError) as err:  # no lock there (filelock: no flock)
        log.debug("%s: built without a lock (%s)", folder, err)
        yield
        return
    try:
        yield
    finally:
        lock.release()
