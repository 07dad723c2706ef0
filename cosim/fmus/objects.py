"""Compiling the native FMUs' binaries: each C file once per platform to an object kept in
the FMU cache, each FMU's library linked from objects, every job in one pool.

The three FMUs share most of their C files (the FMI layer, the native back end, the plant
model): each is compiled once per platform, not once per FMU. An object is kept in
``<cache>/<version>/native-obj/<platform>/<key>.o``, keyed by the C file's content, the
content of every header it includes (``#include "..."``, followed), the FMI headers, the
flags and the compiler (:func:`object_key`), so a rebuild after an edit recompiles only
the files it touched. An object is kept only when its compile printed nothing
(``-Wall -Wextra`` warning-free): a warning fails the build, on every platform.

The compiles of every platform run in one thread pool sized to the cores, then the links
(:func:`build_binaries`). zig links with ``-rtlib=none`` except on Windows
(:meth:`glider_fmi.toolchain.Compiler.link_extra`): no compiler_rt to build first into an
empty zig cache. Windows' C runtime (mingw-w64), which zig builds once into its cache
before its first link for Windows, is started before the compiles, on every core
(:class:`RuntimeWarmer`), and the Windows links come last.
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
import shutil
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from glider_fmi import compile as runtime
from glider_fmi import toolchain

from .files import cache_root, package_version
from .zigcache import (  # noqa: F401 (zig_cache and _zig_has re-exported)
    ZIG_FIRST_BUILD,
    ZIG_WARM_BUILD,
    RuntimeWarmer,
    _home,
    _zig_has,
    start_runtimes,
    zig_cache,
    zig_first_note,
)

if TYPE_CHECKING:
    from ..progress import Progress

log = logging.getLogger(__name__)

#: libraries each OS links (macOS' libm is in libSystem; Windows' in the C runtime)
OS_LIBS = {"linux": ("-lm",), "windows": (), "darwin": ()}
#: the cache folder of the objects, under ``<cache>/<version>/``
OBJECT_DIR = "native-obj"
_INCLUDE = re.compile(rb'^\s*#\s*include\s*"([^"]+)"', re.MULTILINE)


@dataclass(frozen=True)
class Target:
    """One platform of a build: its key, the platform and the compiler building it."""

    key: str
    platform: toolchain.Platform
    compiler: toolchain.Compiler


def local_includes(source: Path) -> list[Path]:
    """The headers ``source`` includes with ``#include "..."`` from its own folder,
    followed into those headers; each once, in the order first met."""
    found: dict[Path, None] = {}
    todo = [source]
    while todo:
        for m in _INCLUDE.finditer(todo.pop().read_bytes()):
            header = source.parent / m.group(1).decode()
            if header.is_file() and header not in found:
                found[header] = None
                todo.append(header)
    return list(found)


def _fmi_headers_digest() -> str:
    folder = runtime.fmi_headers()
    h = hashlib.sha256()
    for p in sorted(folder.glob("*.h")):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()


def compile_flags(target: Target, cflags: tuple[str, ...]) -> list[str]:
    """The flags of an object's compile: ``cflags``, the shared library's code flags and
    link-time optimisation where the compiler makes it
    (:meth:`glider_fmi.toolchain.Compiler.lto_flags`)."""
    shared = target.compiler.shared_flags(target.platform)
    return [
        *cflags,
        *(f for f in shared if f not in ("-shared", "-static-libgcc")),
        *target.compiler.lto_flags(target.platform),
    ]


def link_flags(target: Target, cflags: tuple[str, ...]) -> list[str]:
    """The flags of a library's link: the optimisation level (zig builds its C library
    parts at it; with link-time optimisation, our code too), the shared-library flags,
    link-time optimisation where the compile had it and, for zig but on Windows, no
    compiler_rt (:meth:`glider_fmi.toolchain.Compiler.link_extra`)."""
    flags = [f for f in cflags if f.startswith("-O")]
    flags += target.compiler.shared_flags(target.platform)
    flags += target.compiler.lto_flags(target.platform)
    return [*flags, *target.compiler.link_extra(target.platform)]


def object_key(target: Target, cflags: tuple[str, ...], source: Path, fmi_digest: str) -> str:
    """SHA-256 naming the object of ``source`` for ``target``: the compiler, the platform,
    the flags, the FMI headers (``fmi_digest``), and the content of the file and of every
    header it includes."""
    c = target.compiler
    argv = c.argv(target.platform)[len(c.command) :] if c.is_zig else c.argv(target.platform)
    h = hashlib.sha256("\0".join((c.identity, *argv)).encode())  # zig: any install of it
    h.update("\0".join(compile_flags(target, cflags)).encode())
    h.update(fmi_digest.encode())
    for p in (source, *local_includes(source)):
        h.update(p.name.encode() + b"\0")
        h.update(hashlib.sha256(p.read_bytes()).digest())
    return h.hexdigest()


def _object_folder(fallback: Path) -> Path:
    folder = cache_root() / package_version() / OBJECT_DIR
    try:
        folder.mkdir(parents=True, exist_ok=True)
        if not os.access(folder, os.W_OK):
            raise PermissionError(folder)
    except OSError:  # a cache that cannot be written: objects for this build only
        folder = fallback / OBJECT_DIR
        folder.mkdir(parents=True, exist_ok=True)
    return folder


def _compile(target: Target, cflags: tuple[str, ...], source: Path, obj: Path) -> None:
    import uuid  # a build's alone, not every run's start

    # written in a folder of this call's, under the object's own name (zig's cache keys
    # on the output's name too: a warm zig cache serves an empty FMU cache), then moved
    tmp = obj.parent / f".{os.getpid()}.{uuid.uuid4().hex[:8]}.part"
    tmp.mkdir(parents=True)
    part = tmp / obj.name
    cmd = [
        *target.compiler.argv(target.platform),
        *compile_flags(target, cflags),
        # the importer's headers: clang warns on a prototype-less declaration in fmpy's
        # fmi3FunctionTypes.h, which is not ours to fix
        "-isystem",
        str(runtime.fmi_headers()),
        f"-I{source.parent}",
        "-c",
        str(source),
        "-o",
        str(part),
    ]
    try:
        printed = toolchain.run(cmd, f"{source.name} ({target.key})")
        if printed:
            raise toolchain.ToolchainError(
                f"{source.name} ({target.key}): not warning-free: {printed[:300]}"
            )
        if not part.is_file():
            raise toolchain.ToolchainError(f"compiling {source.name} ({target.key}) wrote no file")
        part.replace(obj)  # complete or absent: another build may read it meanwhile
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _link(target: Target, cflags: tuple[str, ...], objects: list[Path], output: Path) -> None:
    output.parent.mkdir(parents=True, exist_ok=True)
    cmd = [
        *target.compiler.argv(target.platform),
        *link_flags(target, cflags),
        *(str(o) for o in objects),
        "-o",
        str(output),
        *OS_LIBS[target.platform.os],
    ]
    printed = toolchain.run(cmd, output.name)
    if printed:
        raise toolchain.ToolchainError(
            f"linking {output.name} ({target.key}): not warning-free: {printed[:300]}"
        )
    if not output.is_file():
        raise toolchain.ToolchainError(f"linking {output.name} ({target.key}) wrote no file")


def _run_all(jobs: list[Callable[[], None]], workers: int) -> None:
    """Run ``jobs`` in one pool; the first error, after every job has ended."""
    import concurrent.futures  # a build's alone, not a run's

    with concurrent.futures.ThreadPoolExecutor(max(1, workers)) as pool:
        for future in [pool.submit(job) for job in jobs]:
            future.result()


def _shown(
    job: Callable[[], None], label: str, progress: Progress, note: str | None = None
) -> Callable[[], None]:
    """``job``, announced on ``progress`` as it starts (``note`` first, on a line of its own)."""

    def run() -> None:
        if note:
            progress.note(note)
        progress.step(label)
        job()

    return run


def _compile_and_link(
    fmus: dict[str, Iterable[Path]],
    targets: list[Target],
    cflags: tuple[str, ...],
    stage: Path,
    objects: dict[tuple[str, Path], Path],
    compiles: list[Callable[[], None]],
    labels: list[str],
    workers: int,
    warmers: dict[str, RuntimeWarmer],
    progress: Progress | None,
) -> tuple[dict[str, dict[str, Path]], int]:
    """The compiles in one pool, then the links in another, those of the targets whose C
    runtime ``warmers`` build last, each after its warmer: the libraries (FMU name ->
    platform key -> library) and the number of links."""
    noted = set(warmers)
    if progress is not None:
        for key, warmer in warmers.items():
            first = ZIG_FIRST_BUILD[warmer.target.platform.os][0]
            progress.note(f"zig builds {first} for {key} once into {_home(zig_cache())}, "
                          f"beside the compiles ({ZIG_WARM_BUILD})")  # fmt: skip
        progress.set_total(len(compiles) + len(fmus) * len(targets))
        compiles = [_shown(job, label, progress) for job, label in zip(compiles, labels)]
    _run_all(compiles, workers)
    built: dict[str, dict[str, Path]] = {name: {} for name in fmus}
    links: list[Callable[[], None]] = []
    last: list[Callable[[], None]] = []  # the links waiting for a runtime built ahead
    for name, files in fmus.items():
        for t in targets:
            objs = [objects[t.key, p] for p in files if p.suffix == ".c"]
            out = stage / t.key / f"{name}{t.platform.suffix}"
            built[name][t.key] = out
            link = lambda t=t, objs=objs, out=out: _link(t, cflags, objs, out)  # noqa: E731
            if progress is not None:
                note = zig_first_note(t) if t.key not in noted else None
                noted.add(t.key)
                link = _shown(link, f"building {name}.fmu native {t.key}", progress, note)
            if t.key in warmers:
                link = _after(warmers[t.key], link)
            (last if t.key in warmers else links).append(link)
    _run_all(links + last, workers)
    return built, len(links) + len(last)


def _after(warmer: RuntimeWarmer, job: Callable[[], None]) -> Callable[[], None]:
    """``job``, run once ``warmer`` has ended."""

    def run() -> None:
        warmer.wait()
        job()

    return run


@dataclass
class BuildCount:
    """What :func:`build_binaries` did: objects compiled and reused, libraries linked."""

    compiled: int = 0
    reused: int = 0
    linked: int = 0


#: the counts of the last :func:`build_binaries` of this process (tests read it)
LAST = BuildCount()


def build_binaries(
    fmus: dict[str, Iterable[Path]],
    targets: list[Target],
    cflags: tuple[str, ...],
    stage: Path,
    workers: int | None = None,
    progress: Progress | None = None,
) -> dict[str, dict[str, Path]]:
    """Every FMU's library for every target: FMU name -> platform key -> library.

    Parameters
    ----------
    fmus : dict
        FMU name -> its C files (headers are ignored; each ``.c`` is compiled once per
        target however many FMUs list it).
    targets : list of Target
        The platforms to build and their compilers.
    cflags : tuple of str
        The compile flags (``-O`` levels are passed to the link too).
    stage : path
        A temporary folder: the libraries are linked there (``<platform>/<name><suffix>``),
        and the objects too when the cache cannot be written.
    workers : int, optional
        Threads of the pool (default: the machine's cores).
    progress : Progress, optional
        Shows each compile and link as it starts (``compiling plant_model.c for
        x86_64-linux (3 of 12)``, ``building GliderPlant.fmu native x86_64-linux (10 of
        12)``), and zig's one-time build of a platform's C runtime (:func:`zig_first_note`).

    Raises
    ------
    glider_fmi.toolchain.ToolchainError
        A compile or a link failed, or printed a warning (its first lines quoted).
    """
    folder = _object_folder(stage)
    digest = _fmi_headers_digest()
    sources = sorted({p for files in fmus.values() for p in files if p.suffix == ".c"})
    objects: dict[tuple[str, Path], Path] = {}
    compiles: list[Callable[[], None]] = []
    labels: list[str] = []
    for t in targets:
        for src in sources:
            obj = folder / t.key / f"{object_key(t, cflags, src, digest)[:32]}.o"
            objects[t.key, src] = obj
            if not obj.is_file():
                compiles.append(lambda t=t, src=src, obj=obj: _compile(t, cflags, src, obj))
                labels.append(f"compiling {src.name} for {t.key}")
    workers = workers or os.cpu_count() or 1
    warmers = start_runtimes(targets, cflags, stage)  # beside the compiles, on every core
    try:
        built, links = _compile_and_link(fmus, targets, cflags, stage, objects, compiles,
                                         labels, workers, warmers, progress)  # fmt: skip
    finally:
        for warmer in warmers.values():
            warmer.stop()  # ended already, unless a compile or link failed
    LAST.compiled, LAST.reused, LAST.linked = (
        len(compiles), len(objects) - len(compiles), links,
    )  # fmt: skip
    log.info(
        "native build: %d object(s) compiled, %d reused from %s, %d librar(ies) linked",
        LAST.compiled, LAST.reused, folder, LAST.linked,
    )  # fmt: skip
    return built
