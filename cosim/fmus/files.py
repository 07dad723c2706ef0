"""What a built FMU records (package version, flavor) and writing it: a temporary name
first, then renamed into place."""

from __future__ import annotations

import contextlib
import hashlib
import os
import uuid
import zipfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import platformdirs

#: the resource naming an FMU's flavor (``python`` or ``native``)
FLAVOR_FILE = "resources/glider_cosim_flavor.txt"


def package_version() -> str:
    """glider-cosim's version (:data:`glider_cosim.__version__`, which the installed
    metadata is made from): read without ``importlib.metadata``, whose import and lookup
    cost a run 10 ms (issue 48)."""
    from .. import __version__

    return __version__


#: :func:`same_sources`' state: how deep, and the hashes made meanwhile
_SAME_SOURCES: dict[str, Any] = {"on": 0, "hashes": {}}


@contextlib.contextmanager
def same_sources() -> Iterator[None]:
    """Within it, each FMU's source hash (:func:`glider_cosim.fmus.native.native_hash`,
    :func:`glider_cosim.fmus.python.source_hash`) is made once, the sources taken not to
    change: a command's preparation of the cache asks for each 3 times (the folder's key,
    the full set's staleness, the set's), 3-10 ms of a run (issue 48)."""
    _SAME_SOURCES["on"] += 1
    try:
        yield
    finally:
        _SAME_SOURCES["on"] -= 1
        if not _SAME_SOURCES["on"]:
            _SAME_SOURCES["hashes"].clear()


def made_once(key: tuple, make: Any) -> str:
    """``make()``, made once under ``key`` within :func:`same_sources` (each time outside)."""
    if not _SAME_SOURCES["on"]:
        return make()
    made = _SAME_SOURCES["hashes"]
    if key not in made:
        made[key] = make()
    return made[key]


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def fmu_flavor(fmu: Path) -> str | None:
    """The flavor an FMU of ours records ("python", "native"), None if it records none."""
    try:
        with zipfile.ZipFile(fmu) as z:
            return z.read(FLAVOR_FILE).decode().strip() or None
    except (OSError, KeyError, zipfile.BadZipFile):
        return None


@contextlib.contextmanager
def replacing(target: Path) -> Iterator[Path]:
    """A temporary path beside ``target``, unique to this call, moved onto ``target`` in
    one step when the block ends without an error (removed otherwise).

    Two processes building the same FMU at once each write their own file; a reader sees
    the old FMU or a complete new one, never a part.
    """
    part = target.with_name(f".{target.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.part")
    try:
        yield part
        part.replace(target)
    finally:
        part.unlink(missing_ok=True)


#: environment variable naming the cache folder (default: :func:`cache_root`)
CACHE_ENV = "GLIDER_COSIM_CACHE"


def cache_root() -> Path:
    """The per-user cache of built FMUs: ``$GLIDER_COSIM_CACHE`` if set, else
    ``glider-cosim`` in the platform's cache folder (:func:`user_cache`)."""
    own = os.environ.get(CACHE_ENV)
    return Path(own) if own else user_cache() / "glider-cosim"


def user_cache() -> Path:
    """The platform's per-user cache folder, as platformdirs finds it: ``$XDG_CACHE_HOME``
    or ``~/.cache`` on Linux, ``~/Library/Caches`` on macOS, ``%LOCALAPPDATA%`` on Windows
    (where zig keeps its cache too)."""
    return Path(platformdirs.user_cache_dir())


def build_progress(
    todo: Iterable[Any], flavor: str, fmi: int, out: Path, platforms: Iterable[str]
) -> Any:
    """The :class:`~glider_cosim.progress.Progress` of a build of the FMUs ``todo`` (each
    with a ``name``), its first line naming them, the flavor, the FMI version, the
    platforms and the folder: ``building GliderPlant, GliderObserver, GliderController
    (native, FMI 2.0, for x86_64-linux) into ~/.cache/glider-cosim/...``. Its steps are
    set by the build."""
    from ..progress import Progress, home

    names = ", ".join(c.name for c in todo)
    header = (f"building {names} ({flavor}, FMI {fmi}.0, for {', '.join(platforms)}) into "
              f"{home(Path(out).absolute())}")  # fmt: skip
    return Progress(1, "build", header)
