"""The per-user cache of built FMUs (``glider-cosim cache``): what it holds, and pruning
the sets of other glider-cosim versions.

Layout: ``<cache_root>/<version>/<entry>``, where an entry is an FMU set
``<flavor>[-fmi3]-<sources key>`` (:func:`glider_cosim.fmus.folders.cache_dir`), a
set with this machine's binary alone, to run here
``native[-fmi3]-only-<platform>-<sources key>`` or ``python-only-<platform>-<sources
key>``, the compiled fast loop
``fastloop-<key>``, the native sources ``native-src`` or their objects ``native-obj``
(:mod:`glider_cosim.fmus.objects`), the native FMUs' variable tables ``native-vars``,
the cache's FMUs unpacked to run ``unpacked``, matplotlib's font cache ``matplotlib`` (the CLI's).
``--prune`` removes every version folder but the installed version's. The installed
version's sets built from other sources (an edited checkout, another branch) are kept
and listed as such: switching back to those sources reuses them.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .files import cache_root, package_version

#: the FMU-set kinds of a cache entry's name (``<kind>-<key>``)
FMU_KINDS = ("python", "native", "python-fmi3", "native-fmi3")


@dataclass(frozen=True)
class CacheEntry:
    """One folder of the cache: ``<version>/<name>``, its size (bytes) and what it is."""

    path: Path
    version: str
    name: str
    size: int
    what: str


def folder_size(path: Path) -> int:
    """Bytes of the regular files under ``path`` (links not followed)."""
    if path.is_file() or path.is_symlink():
        return path.lstat().st_size
    return sum(f.lstat().st_size for f in path.rglob("*") if f.is_file() and not f.is_symlink())


def _current_keys() -> dict[str, str]:
    """Kind -> the sources key this install builds (unknown kinds are missing)."""
    from .folders import sources_key
    from .native_vars import tables_not_kept

    keys = {}
    for flavor in ("python", "native"):
        try:
            with tables_not_kept():  # listed, not added to
                key = sources_key(flavor)
        except (OSError, ValueError):  # no compiler to fingerprint for native
            continue
        keys[flavor] = keys[f"{flavor}-fmi3"] = key
    return keys


def _describe(version: str, name: str, keys: dict[str, str]) -> str:
    kind, _, key = name.rpartition("-")
    if name == "native-src":
        return "native sources' builds"
    if name == "native-obj":
        return "native objects (each C file compiled per platform)"
    if name == "native-vars":
        return "native FMUs' variable tables (generated from the Python slaves)"
    if name == "unpacked":
        return "the cache's FMUs unpacked to run (one folder per FMU file)"
    if name == "locks":
        return "the build locks of FMU folders (one file per folder)"
    if name == "matplotlib":
        return "matplotlib's font cache (the sweep's and report's figures)"
    kind, only, host = kind.partition("-only-")
    if kind in FMU_KINDS:
        flavor, _, fmi = kind.partition("-")
        label = f"{flavor} FMUs, FMI {'3.0' if fmi else '2.0'}"
        if only:
            label += f", {host} only (to run here)"
        if version != package_version():
            return f"{label}, other version"
        return f"{label}, {'current sources' if keys.get(kind) == key else 'other sources'}"
    if kind == "fastloop":
        return "compiled fast loop"
    return "other"


def _version_dirs(root: Path | None) -> list[Path]:
    """The cache's version folders, sorted (none if the cache does not exist)."""
    root = cache_root() if root is None else Path(root)
    return sorted(p for p in root.iterdir() if p.is_dir()) if root.is_dir() else []


def cache_entries(root: Path | None = None) -> list[CacheEntry]:
    """Every folder of the cache, by version then name.

    Parameters
    ----------
    root : path, optional
        The cache folder (default :func:`glider_cosim.fmus.files.cache_root`).

    Returns
    -------
    list of CacheEntry
        Empty when the cache does not exist.
    """
    keys = _current_keys()
    entries = []
    for vdir in _version_dirs(root):
        for item in sorted(vdir.iterdir()):
            what = _describe(vdir.name, item.name, keys) if item.is_dir() else "file"
            entries.append(CacheEntry(item, vdir.name, item.name, folder_size(item), what))
    return entries


def human_size(size: int) -> str:
    """``size`` bytes as B, kB, MB or GB (powers of 1000, one decimal)."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if size >= scale:
            return f"{size / scale:.1f} {unit}"
    return f"{size} B"


def other_versions(root: Path | None = None) -> list[Path]:
    """The version folders of the cache that are not the installed version's."""
    mine = package_version()
    return [p for p in _version_dirs(root) if p.name != mine]


def prune(root: Path | None = None) -> list[tuple[Path, int]]:
    """Remove the cache's folders of other glider-cosim versions.

    Parameters
    ----------
    root : path, optional
        The cache folder (default :func:`glider_cosim.fmus.files.cache_root`).

    Returns
    -------
    list of (path, int)
        Each version folder removed and the bytes it held.

    Raises
    ------
    OSError
        A folder could not be removed (the ones before it are gone).
    """
    removed = []
    for vdir in other_versions(root):
        size = folder_size(vdir)
        shutil.rmtree(vdir)
        removed.append((vdir, size))
    return removed


def cache_report(do_prune: bool = False, write: Callable[[str], object] = print) -> None:
    """``glider-cosim cache [--prune]``: list the cache, or prune it and say what went.

    Parameters
    ----------
    do_prune : bool
        Remove the other versions' folders (:func:`prune`) instead of listing.
    write : callable
        Called with each output line.
    """
    root = cache_root()
    if do_prune:
        removed = prune(root)
        for path, size in removed:
            write(f"removed {path} ({human_size(size)})")
        if removed:
            total = human_size(sum(size for _, size in removed))
            write(f"pruned {len(removed)} version folder(s) of {root}, freed {total}")
        else:
            write(f"nothing to prune: {root} holds no other version than {package_version()}")
        return
    entries = cache_entries(root)
    if not entries:
        write(f"{root}: empty")
        return
    write(f"{root} (glider-cosim {package_version()}):")
    width = max(len(f"{e.version}/{e.name}") for e in entries)
    for e in entries:
        write(f"  {e.version + '/' + e.name:<{width}}  {human_size(e.size):>8}  {e.what}")
    total = human_size(sum(e.size for e in entries))
    others = other_versions(root)
    tail = (
        f"; {len(others)} other version(s): glider-cosim cache --prune removes them"
        if others
        else ""
    )
    write(f"total {total} in {len(entries)} folder(s){tail}")
