"""The C toolchain of every build: zig's C compiler from PyPI, or a system compiler chosen.

``pip install`` brings the ``ziglang`` package: ``python -m ziglang cc`` is clang with
the C libraries and headers of every platform we ship (glibc at any version, mingw-w64's
Windows runtime, macOS' libSystem stubs), so one machine builds every platform offline
with no system compiler, no mingw-w64 and no Python headers. Linux binaries are linked
against glibc 2.17 (manylinux2014's baseline: RHEL 7 and later).

A system compiler may be chosen instead (``--compiler``, or ``$GLIDER_COSIM_COMPILER``):
a comma-separated list of C compiler commands (``gcc``, ``clang``, ``cc``,
``x86_64-w64-mingw32-gcc``, a path), each building the platform it targets (asked with
``-dumpmachine``), and zig the others (``zig`` alone, the default, builds all).
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

#: environment variable holding the default of ``--compiler``
COMPILER_ENV = "GLIDER_COSIM_COMPILER"


@dataclass(frozen=True)
class Platform:
    """A platform we build binaries for."""

    key: str  # FMI 3's platform tuple, e.g. "x86_64-linux"
    zig_target: str  # zig's target (glibc version included on Linux)
    os: str  # "linux", "windows" or "darwin"
    arch: str  # "x86_64" or "aarch64"
    suffix: str  # ".so", ".dll", ".dylib"

    @property
    def fmi3_dir(self) -> str:
        return f"binaries/{self.key}"


#: every platform of the native FMUs, in build order
PLATFORMS: dict[str, Platform] = {
    p.key: p
    for p in (
        Platform("x86_64-linux", "x86_64-linux-gnu.2.17", "linux", "x86_64", ".so"),
        Platform("aarch64-linux", "aarch64-linux-gnu.2.17", "linux", "aarch64", ".so"),
        Platform("x86_64-windows", "x86_64-windows-gnu", "windows", "x86_64", ".dll"),
        Platform("x86_64-darwin", "x86_64-macos", "darwin", "x86_64", ".dylib"),
        Platform("aarch64-darwin", "aarch64-macos", "darwin", "aarch64", ".dylib"),
    )
}
#: the highest glibc symbol version a Linux binary may need
GLIBC_MAX = (2, 17)


class ToolchainError(OSError):
    """The chosen compiler cannot be used (not installed, unknown target)."""


@dataclass(frozen=True)
class Compiler:
    """One C compiler and the platforms it builds."""

    name: str  # "zig" or the command as given
    command: tuple[str, ...]  # without the target
    platforms: frozenset[str]
    identity: str  # version text, for the FMUs' staleness hashes

    @property
    def is_zig(self) -> bool:
        return self.name == "zig"

    def argv(self, platform: Platform) -> list[str]:
        """The command line's start for ``platform`` (zig: with its ``-target``)."""
        if self.is_zig:
            return [*self.command, "-target", platform.zig_target]
        return list(self.command)

    def shared_flags(self, platform: Platform) -> tuple[str, ...]:
        """Flags that make a shared library for ``platform`` exporting only the FMI
        functions (marked by the FMI headers' export macros)."""
        if platform.os == "windows":
            return ("-shared",) if self.is_zig else ("-shared", "-static-libgcc")
        return ("-fPIC", "-shared", "-fvisibility=hidden")

    def lto_flags(self, platform: Platform) -> tuple[str, ...]:
        """Link-time optimisation, on the compile and the link: for zig on Linux only.
        Across the FMI layer, the back end and the model glue (separate C files, calling
        each other through tables of function pointers) it inlines and resolves those
        calls: a native run 0.06 us a step faster, 0.035 of it FMI overhead (alternated in
        one process; bench/overhead_timed.py). zig refuses it for macOS ("LTO requires
        using LLD") and its Windows link loses MinGW's math symbols (frexpf, lrintl, ...);
        other compilers would need their linker's plugin."""
        return ("-flto",) if self.is_zig and platform.os == "linux" else ()

    def link_extra(self, platform: Platform) -> tuple[str, ...]:
        """Flags a shared library's link adds: for zig but on Windows, no compiler_rt
        (``-rtlib=none``). Our libraries call nothing of it on Linux and macOS (the same
        bytes with and without it), and zig would first build it for each target into an
        empty cache (a fresh machine), 5-10 s each; Windows' stack probe
        (``___chkstk_ms``) is in it."""
        return ("-rtlib=none",) if self.is_zig and platform.os != "windows" else ()


def zig_available() -> bool:
    return importlib.util.find_spec("ziglang") is not None


@functools.cache
def zig_version() -> str:
    """The installed ziglang's version ("" if none); read once a process (each FMU's
    staleness hash asks for it), from its ``.dist-info`` beside the package, else
    ``importlib.metadata`` (whose import costs a run 5-10 ms, issue 48)."""
    spec = importlib.util.find_spec("ziglang")
    if spec is not None and spec.origin is not None:
        infos = list(Path(spec.origin).parent.parent.glob("ziglang-*.dist-info"))
        if len(infos) == 1:
            with contextlib.suppress(OSError, UnicodeDecodeError):
                for line in (infos[0] / "METADATA").read_text(encoding="utf-8").splitlines():
                    if line.startswith("Version:"):
                        return line.partition(":")[2].strip()
                    if not line.strip():
                        break  # the headers end: no version there
    from importlib import metadata

    try:
        return metadata.version("ziglang")
    except metadata.PackageNotFoundError:
        return ""


def zig_command() -> tuple[str, ...]:
    """zig's C compiler from the ziglang package: its ``zig`` binary with ``cc`` (what
    ``python -m ziglang cc`` starts, without an interpreter started first for each of a
    build's 60 compiles and links), else ``python -m ziglang cc`` with this interpreter."""
    spec = importlib.util.find_spec("ziglang")
    if spec is not None and spec.origin is not None:
        binary = os.path.join(os.path.dirname(spec.origin), "zig.exe" if os.name == "nt" else "zig")
        if os.access(binary, os.X_OK):
            return (binary, "cc")
    return (sys.executable, "-m", "ziglang", "cc")


def _platform_of(triple: str) -> str | None:
    """Our platform key for a compiler's ``-dumpmachine`` triple, or None."""
    t = triple.strip().lower()
    arch = t.split("-", 1)[0]
    arch = {"amd64": "x86_64", "arm64": "aarch64"}.get(arch, arch)
    if "mingw" in t or "windows" in t:
        system = "windows"
    elif "darwin" in t or "apple" in t or "macos" in t:
        system = "darwin"
    elif "linux" in t:
        system = "linux"
    else:
        return None
    key = f"{arch}-{system}"
    return key if key in PLATFORMS else None


@functools.lru_cache(maxsize=32)
def _system_compiler(name: str) -> Compiler:
    found = shutil.which(name)
    if found is None:
        raise ToolchainError(
            f"--compiler {name}: not found on PATH (the default, zig, comes with "
            "'pip install': python -m ziglang cc)"
        )
    try:
        machine = subprocess.run([found, "-dumpmachine"], capture_output=True, text=True,
                                 timeout=30, check=False)  # fmt: skip
        version = subprocess.run([found, "--version"], capture_output=True, text=True,
                                 timeout=30, check=False)  # fmt: skip
    except (OSError, subprocess.TimeoutExpired) as err:
        raise ToolchainError(f"--compiler {name}: cannot run {found}: {err}") from None
    key = _platform_of(machine.stdout)
    if machine.returncode != 0 or key is None:
        raise ToolchainError(
            f"--compiler {name}: its target {machine.stdout.strip() or '(none)'!r} is none "
            f"of ours ({', '.join(PLATFORMS)})"
        )
    first = (version.stdout.strip().splitlines() or [""])[0]
    return Compiler(name, (found,), frozenset({key}), f"{first} {machine.stdout.strip()}")


@dataclass(frozen=True)
class Toolchain:
    """The compilers of a build: which one builds each platform."""

    compilers: tuple[Compiler, ...]
    spec: str

    def for_platform(self, key: str) -> Compiler | None:
        """The compiler building platform ``key`` (the first listed that targets it)."""
        return next((c for c in self.compilers if key in c.platforms), None)

    def fingerprint(self) -> str:
        """The compilers' identities and the platforms each optimises at link time, for
        the FMUs' staleness hashes."""
        return ";".join(
            f"{sorted(c.platforms)}={c.identity}"
            f" lto {sorted(k for k in c.platforms if c.lto_flags(PLATFORMS[k]))}"
            for c in self.compilers
        )


def select(spec: str | None = None) -> Toolchain:
    """The toolchain ``spec`` names (``--compiler``): None is ``$GLIDER_COSIM_COMPILER``,
    else ``zig``.

    Raises
    ------
    ToolchainError
        A compiler named is not installed or targets none of our platforms, or zig is
        asked for and not installed.
    """
    if spec is None:
        spec = os.environ.get(COMPILER_ENV, "").strip() or "zig"
    names = [n.strip() for n in spec.split(",") if n.strip()] or ["zig"]
    compilers = [_system_compiler(n) for n in names if n != "zig"]
    if "zig" in names or zig_available():
        if not zig_available():
            raise ToolchainError(
                "--compiler zig: the ziglang package is not installed (it is a dependency "
                "of glider-cosim: pip install ziglang)"
            )
        compilers.append(
            Compiler("zig", zig_command(), frozenset(PLATFORMS), f"ziglang {zig_version()}")
        )
    return Toolchain(tuple(compilers), spec)


def fingerprint(chain: Toolchain | None = None) -> str:
    """``chain``'s fingerprint (default: :func:`select`'s), for staleness hashes; the error
    text when no toolchain can be chosen (the build itself then reports it)."""
    try:
        return (chain or select()).fingerprint()
    except ToolchainError as err:
        return f"no toolchain: {err}"


def host_machine() -> tuple[str, str]:
    """This machine's system (``linux``, ``windows``, ``darwin``, else ``sys.platform``)
    and architecture as we name them (``x86_64``, ``aarch64``, else the machine's own
    lower-case name): the one reading of the machine, for our platform key and for the
    binaries folder a host loads (:mod:`glider_cosim.inputs.archives`)."""
    if sys.platform == "win32":
        import platform as _platform  # os.uname is POSIX's

        machine = _platform.machine().lower()
    else:
        machine = os.uname().machine.lower()
    system = {"linux": "linux", "win32": "windows", "darwin": "darwin"}.get(
        sys.platform, sys.platform
    )
    return system, {"amd64": "x86_64", "arm64": "aarch64"}.get(machine, machine)


def host_platform() -> str | None:
    """This machine's platform key (None for one we do not build)."""
    system, arch = host_machine()
    key = f"{arch}-{system}"
    return key if key in PLATFORMS else None


def run(cmd: list[str], what: str) -> str:
    """Run a compiler command; what it printed (empty when warning-free).

    No time limit: a slow machine is slow, not failed (a cold zig build of a C runtime on
    a loaded machine takes minutes); the build's progress shows each compile as it starts,
    and a bar's clock runs meanwhile.

    Raises
    ------
    ToolchainError
        The compiler could not be started or failed (its first lines quoted).
    """
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    except OSError as err:
        raise ToolchainError(f"compiling {what} with {cmd[0]} failed: {err}") from None
    if proc.returncode != 0:
        first = " ".join((proc.stderr or proc.stdout).strip().splitlines()[:3])
        raise ToolchainError(
            f"compiling {what} with {cmd[0]} failed (exit {proc.returncode}): {first}"
        )
    return (proc.stderr + proc.stdout).strip()


def host_command(chain: Toolchain | None = None, lto: bool = False) -> list[str]:
    """The start of a command line building a shared library this process loads (the
    master's C loop, the container's forwarder): the toolchain's compiler for this
    machine's platform, with its target and shared-library flags; ``lto``: and its
    link-time optimisation (:meth:`Compiler.lto_flags`), for a helper that must be built
    as the native FMUs are (the floor's models).

    Raises
    ------
    ToolchainError
        This machine is none of our platforms, or no compiler chosen builds it.
    """
    key = host_platform()
    chain = chain or select()
    compiler = chain.for_platform(key) if key else None
    if compiler is None:
        raise ToolchainError(f"no compiler for this machine ({key}) in --compiler {chain.spec}")
    platform = PLATFORMS[key]
    shared = [f for f in compiler.shared_flags(platform) if f != "-fvisibility=hidden"]
    optimise = compiler.lto_flags(platform) if lto else ()
    return [*compiler.argv(platform), *shared, *optimise, *compiler.link_extra(platform)]
