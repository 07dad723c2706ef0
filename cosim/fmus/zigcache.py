"""zig's C runtimes in its global cache: whether it holds a platform's
(:func:`zig_first_note`, the wait named before a machine's first build), and Windows'
mingw-w64 runtime built ahead of the links, on every core (:class:`RuntimeWarmer`)."""

from __future__ import annotations

import logging
import os
import subprocess
from pathlib import Path
from typing import Any

from glider_fmi import toolchain

from .files import user_cache

#: a build target, :class:`glider_cosim.fmus.objects.Target` (its platform, compiler and key)
Target = Any

log = logging.getLogger(__name__)

#: zig's first build of a target's C runtime into its cache: the time it takes here, by OS
ZIG_FIRST_BUILD = {"windows": ("its C runtime (mingw-w64)", "about 2 min"),
                   "linux": ("its glibc stubs", "about 5 s")}  # fmt: skip
#: zig's first build of Windows' C runtime when :class:`RuntimeWarmer` builds it, on every core
ZIG_WARM_BUILD = "about 1 min"
#: threads of zig's pool that its C runtime's build holds waiting (its sub-builds): with
#: ``-j2`` (``zig cc``'s default on two cores) zig compiles the runtime's C files one at a
#: time, with ``-j3`` at most one, ``-j4`` and ``-j5`` one or two, ``-j6`` two (sampled)
RUNTIME_JOBS_HELD = 4
#: zig's optimisation mode for each ``-O`` level of ``zig cc`` (its C runtime is cached per mode)
ZIG_MODES = {"-O0": "Debug", "-O2": "ReleaseFast", "-O3": "ReleaseFast",
             "-Os": "ReleaseSmall", "-Oz": "ReleaseSmall"}  # fmt: skip
#: ELF machine numbers of zig's glibc stubs (``libc.so.6`` in its cache), by arch
_ELF_MACHINE = {"x86_64": 62, "aarch64": 183}


def zig_cache() -> Path:
    """zig's global cache: ``$ZIG_GLOBAL_CACHE_DIR``, else ``zig`` in the platform's cache
    folder (:func:`~glider_cosim.fmus.files.user_cache`)."""
    own = os.environ.get("ZIG_GLOBAL_CACHE_DIR")
    return Path(own) if own else user_cache() / "zig"


def _zig_has(platform: toolchain.Platform) -> bool:
    """True if zig's cache holds the C runtime pieces it links ``platform`` with (mingw-w64's
    ``libmingw32.lib``; a ``libc.so.6`` stub of the platform's architecture)."""
    objects = zig_cache() / "o"
    try:
        if platform.os == "windows":
            return any(objects.glob("*/libmingw32.lib"))
        for stub in objects.glob("*/libc.so.6"):
            with stub.open("rb") as f:
                head = f.read(20)
            if len(head) == 20 and int.from_bytes(head[18:20], "little") == _ELF_MACHINE.get(
                platform.arch
            ):
                return True
    except OSError:
        return False
    return False


def zig_first_note(target: Target) -> str | None:
    """A line naming zig's one-time build of ``target``'s C runtime into its cache, when
    zig builds it and its cache does not hold it yet (None otherwise): the wait of a
    machine's first build, e.g. "zig builds its C runtime (mingw-w64) for x86_64-windows
    once into ~/.cache/zig (about 2 min)"."""
    first = ZIG_FIRST_BUILD.get(target.platform.os)
    if first is None or not target.compiler.is_zig or _zig_has(target.platform):
        return None
    return f"zig builds {first[0]} for {target.key} once into {_home(zig_cache())} ({first[1]})"


def _home(path: Path) -> str:
    from ..progress import home  # a build's alone

    return home(path)


class RuntimeWarmer:
    """zig's one-time build of Windows' C runtime (mingw-w64, its ``libmingw32.lib`` of
    some 440 C files, compiler_rt and the import libraries) into its cache, started at
    once in a process of its own.

    ``zig cc`` builds that runtime at its first link for Windows, compiling its C files
    one at a time (zig's pool has a thread per core, and the runtime's sub-builds hold
    them waiting): about 70 s of one core here. ``zig build-lib`` of an empty library
    for the same target and optimisation mode, with a pool large enough to compile on
    every core (:data:`RUNTIME_JOBS_HELD`), builds the same runtime under the same cache
    keys, and the links find it there: the same objects of ours, the same runtime code,
    the same link command line. Started before the compiles, it runs
    beside them and the other platforms' links; the Windows links wait for it
    (:meth:`wait`). Nothing depends on it: when it fails or builds another variant, the
    links build what they need as before.
    """

    def __init__(self, target: Target, cflags: tuple[str, ...], folder: Path) -> None:
        self.target = target
        self.folder = folder
        self.process: subprocess.Popen[bytes] | None = None
        command = self.command(target, cflags, folder)
        if command is None:
            return
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "glider_runtime.c").write_text("int glider_runtime(void) { return 0; }\n")
        try:
            with (folder / "zig.log").open("wb") as log_file:
                self.process = subprocess.Popen(command, stdin=subprocess.DEVNULL,
                                                stdout=log_file, stderr=log_file)  # fmt: skip
        except OSError as err:  # the link will say what is wrong
            log.info("zig's C runtime for %s not started ahead: %s", target.key, err)

    @staticmethod
    def command(target: Target, cflags: tuple[str, ...], folder: Path) -> list[str] | None:
        """The ``zig build-lib`` building ``target``'s C runtime into zig's cache (its
        empty library and local cache in ``folder``), or None: not zig's, not Windows, or
        an ``-O`` level of no known mode (:data:`ZIG_MODES`)."""
        c = target.compiler
        level = next((f for f in reversed(cflags) if f.startswith("-O")), "-O0")
        mode = ZIG_MODES.get(level)
        if not c.is_zig or target.platform.os != "windows" or mode is None:
            return None
        return [
            *c.command[:-1],  # zig (or python -m ziglang) without "cc"
            "build-lib",
            "-target",
            target.platform.zig_target,
            "-O",
            mode,
            "-dynamic",
            "-lc",
            f"-j{(os.cpu_count() or 1) + RUNTIME_JOBS_HELD}",
            str(folder / "glider_runtime.c"),
            f"-femit-bin={folder / 'glider_runtime.dll'}",
            "--cache-dir",
            str(folder / "zig-local"),
        ]

    @property
    def started(self) -> bool:
        return self.process is not None

    def wait(self) -> None:
        """Wait until the runtime is built (or its build ended); a failure is logged, the
        link then builds what it needs."""
        if self.process is not None and self.process.wait() != 0:
            text = (self.folder / "zig.log").read_text(errors="replace")[-300:]
            log.info("zig's C runtime for %s, built ahead, failed: %s", self.target.key, text)

    def stop(self) -> None:
        """End the build if it still runs (a failed build of ours), and reap it."""
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


def start_runtimes(
    targets: list[Target], cflags: tuple[str, ...], stage: Path
) -> dict[str, RuntimeWarmer]:
    """A :class:`RuntimeWarmer` started for each target whose C runtime zig builds at its
    first link and its cache does not hold yet (Windows'): platform key -> warmer."""
    warmers = {}
    for t in targets:
        if RuntimeWarmer.command(t, cflags, stage) is not None and not _zig_has(t.platform):
            warmer = RuntimeWarmer(t, cflags, stage / f"zig-runtime-{t.key}")
            if warmer.started:
                warmers[t.key] = warmer
    return warmers
