"""Compile the FMI runtime and record the Python it starts in hosts without one.

The runtime (the FMI layer ``fmi2_layer.c`` with the Python back end ``backend_python.c``,
next to this module) is compiled with the build's toolchain (:mod:`glider_fmi.toolchain`:
zig's C compiler from PyPI by default, for Linux x86_64 and aarch64 at glibc 2.17)
against the FMI headers fmpy ships and ``glider_python.h``, our declaration of the
stable-ABI (limited API 3.11) functions it calls: no Python headers. It links no
libpython: every Python function is resolved when the first FMU is instantiated, so one
binary serves hosts on Python 3.11 and later, and hosts without Python, where it loads
and starts the libpython recorded by :func:`python_config`.
"""

from __future__ import annotations

import hashlib
import importlib.util
import logging
import sys
import sysconfig
from collections.abc import Sequence
from pathlib import Path

from . import toolchain

#: every C file of the runtime, compiled into one library: the FMI layer (one state
#: machine, every FMU), the Python back end, finding a Python on the target, and the GIL
#: with one thread state kept per host thread
LAYER_SOURCES = tuple(Path(__file__).with_name(n) for n in ("fmi_layer.c", "fmi2_layer.c"))
#: the FMI 3.0 front end, in place of fmi2_layer.c in an FMI 3 build
FMI3_FRONT_END = Path(__file__).with_name("fmi3_layer.c")
PYTHON_BACKEND_SOURCES = tuple(
    Path(__file__).with_name(n) for n in ("backend_python.c", "python_find.c", "python_threads.c")
)
RUNTIME_SOURCES = LAYER_SOURCES + PYTHON_BACKEND_SOURCES
RUNTIME_HEADERS = tuple(
    Path(__file__).with_name(n)
    for n in (
        "fmi_layer.h",
        "python_find.h",
        "python_threads.h",
        "glider_python.h",
        "bundle_loader.h",
        "glider_fp.h",
    )
)
#: the platforms the Python flavor's runtime is built for (its back end is POSIX and
#: finds ``libpython3.X.so``: Linux)
PYTHON_PLATFORMS = ("x86_64-linux", "aarch64-linux")
#: file in the FMU's resources/ naming the Python to start in a host without one
PYTHON_CONFIG_FILE = "glider_fmi_python.cfg"
#: environment variable naming another such file (another Python installation)
PYTHON_CONFIG_ENV = "GLIDER_FMI_PYTHON_CONFIG"
CFLAGS = ("-std=gnu11", "-O2", "-fPIC", "-shared", "-fvisibility=hidden", "-Wall", "-Wextra")
LIBS = ("-ldl", "-lpthread", "-lm")
#: packages whose site folders the configuration records as a last resort (``site=``):
#: everything our FMUs import is the standard library or bundled in ``resources/``
#: (pythonfmu's pure-Python part included); these serve users' own slaves built with
#: ``build_slave_fmu`` that import them, on the building installation only
PYTHON_PACKAGES = ("numpy", "scipy")


class RuntimeBuildError(toolchain.ToolchainError):
    """The runtime cannot be compiled here (no compiler for a platform, a compiler error)."""


def fmi_headers() -> Path:
    """The folder of the FMI headers fmpy ships (``fmi2Functions.h`` and the FMI 3 ones)."""
    spec = importlib.util.find_spec("fmpy")
    if spec is None or spec.origin is None:
        raise RuntimeBuildError("fmpy is not installed: its FMI 2.0 headers are needed")
    fmi_include = Path(spec.origin).parent / "c-code"
    if not (fmi_include / "fmi2Functions.h").is_file():
        raise RuntimeBuildError(f"fmi2Functions.h not found in {fmi_include}")
    return fmi_include


def _include_dirs() -> list[str]:
    return [str(fmi_headers())]


def runtime_sources(fmi3: bool = False) -> tuple[Path, ...]:
    """The runtime's C files, with the FMI 3.0 front end instead of FMI 2.0's if ``fmi3``."""
    if not fmi3:
        return RUNTIME_SOURCES
    return tuple(FMI3_FRONT_END if p.name == "fmi2_layer.c" else p for p in RUNTIME_SOURCES)


def _compiler(platform: str, chain: toolchain.Toolchain | None) -> toolchain.Compiler:
    chain = chain or toolchain.select()
    compiler = chain.for_platform(platform)
    if compiler is None:
        raise RuntimeBuildError(
            f"no compiler for {platform} in --compiler {chain.spec} (add zig, the default)"
        )
    return compiler


def compile_command(
    output: Path,
    fmi3: bool = False,
    platform: str = "x86_64-linux",
    chain: toolchain.Toolchain | None = None,
) -> list[str]:
    """The compiler command line that builds the runtime for ``platform`` into ``output``."""
    compiler = _compiler(platform, chain)
    includes = [f for d in _include_dirs() for f in ("-isystem", d)]  # the FMI headers
    sources = [str(p) for p in runtime_sources(fmi3)]
    argv = compiler.argv(toolchain.PLATFORMS[platform])
    return [*argv, *CFLAGS, *includes, *sources, "-o", str(output), *LIBS]


def runtime_fingerprint(fmi3: bool = False, chain: toolchain.Toolchain | None = None) -> str:
    """SHA-256 over the runtime's sources, its compile flags and the compilers' versions
    (FMU staleness)."""
    h = hashlib.sha256()
    for p in (*runtime_sources(fmi3), *RUNTIME_HEADERS):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    h.update(" ".join((*CFLAGS, *LIBS)).encode())
    h.update(toolchain.fingerprint(chain).encode())
    return h.hexdigest()


def compile_runtime(
    output: Path | str,
    fmi3: bool = False,
    platform: str = "x86_64-linux",
    chain: toolchain.Toolchain | None = None,
) -> str:
    """Compile the runtime for ``platform`` into ``output`` (a shared library; FMI 3.0's
    functions if ``fmi3``, else FMI 2.0's).

    Returns
    -------
    str
        What the compiler printed (empty when it built warning-free).

    Raises
    ------
    RuntimeBuildError
        No compiler for the platform, or the compiler failed (its first lines quoted).
    """
    output = Path(output)
    cmd = compile_command(output, fmi3, platform, chain)
    try:
        printed = toolchain.run(cmd, f"the FMI runtime ({platform})")
    except toolchain.ToolchainError as err:
        raise RuntimeBuildError(str(err)) from None
    if not output.is_file():
        raise RuntimeBuildError(f"compiling the FMI runtime ({platform}) wrote no {output.name}")
    return printed


def compile_runtimes(
    folder: Path | str,
    fmi3: bool = False,
    chain: toolchain.Toolchain | None = None,
    platforms: Sequence[str] = PYTHON_PLATFORMS,
) -> dict[str, Path]:
    """The runtime for every platform of ``platforms`` (default :data:`PYTHON_PLATFORMS`)
    the toolchain builds, warning-free, in ``folder``: platform -> library. Platforms no
    compiler chosen builds (a system compiler without zig) are left out with a one-line
    warning."""
    chain = chain or toolchain.select()
    missing = [p for p in platforms if chain.for_platform(p) is None]
    if len(missing) == len(platforms):
        raise RuntimeBuildError(
            f"--compiler {chain.spec} builds none of {', '.join(platforms)} (add zig, the default)"
        )
    if missing:
        logging.getLogger(__name__).warning(
            "--compiler %s builds no %s: the Python FMUs leave it out", chain.spec,
            ", ".join(missing),
        )  # fmt: skip
    built = {}
    for platform in platforms:
        if platform in missing:
            continue
        out = Path(folder) / f"runtime{3 if fmi3 else 2}-{platform}.so"
        printed = compile_runtime(out, fmi3, platform, chain)
        if printed:
            raise RuntimeBuildError(
                f"the FMI runtime ({platform}) is not warning-free: {printed[:300]}"
            )
        built[platform] = out
    return built


def libpython() -> Path:
    """Path of the running interpreter's shared libpython.

    Raises
    ------
    RuntimeBuildError
        The interpreter was built without ``--enable-shared`` (no shared library).
    """
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    names = [sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LDLIBRARY")]
    for name in names:
        if name and (name.endswith((".so", ".dylib")) or ".so." in name):
            for folder in (libdir, sysconfig.get_config_var("LIBPL") or ""):
                p = Path(folder) / name
                if p.is_file():
                    return p
    raise RuntimeBuildError(
        f"libpython: no shared library {names[0] or names[1]!r} in {libdir!r}: this Python "
        "was built without --enable-shared, so a host without Python cannot start it"
    )


def site_dirs() -> list[str]:
    """Folders a started interpreter adds with ``site.addsitedir``: those the packages the
    slaves import are installed in, then this interpreter's site-packages.

    From the installed distributions, not from where the modules were imported: in a
    process that ran our FMUs, ``pythonfmu`` comes from an FMU's ``resources/`` (a
    temporary folder), which must not end up in an FMU (nor change its build hash).
    """
    import importlib.metadata  # here: the run's imports of this module need none

    dirs = []
    for name in PYTHON_PACKAGES:
        try:
            dist = importlib.metadata.distribution(name)
        except importlib.metadata.PackageNotFoundError:
            continue
        dirs.append(str(Path(str(dist.locate_file(""))).resolve()))
    scheme = sysconfig.get_paths()
    dirs += [scheme["purelib"], scheme["platlib"]]
    dirs += [p for p in sys.path if p.endswith(("site-packages", "dist-packages"))]
    return [d for d in dict.fromkeys(dirs) if Path(d).is_dir()]


def python_config() -> str:
    """The runtime's Python configuration for this interpreter (key=value lines).

    ``libpython`` is loaded and started by the runtime in a host without Python, with
    ``PYTHONHOME`` = ``home`` (unless the host sets one); each ``site`` folder is then
    added with ``site.addsitedir``; ``executable`` becomes ``sys.executable``. Without a
    shared libpython the file says so and such hosts get a one-line error.
    """
    lines = [
        "# Python the glider-cosim FMI runtime starts in a host without Python",
        f"# (override: ${PYTHON_CONFIG_ENV}=FILE in this format; glider-cosim host-env --config)",
    ]
    try:
        lines.append(f"libpython={libpython()}")
    except RuntimeBuildError as err:
        lines.append(f"# {err}")
    lines.append(f"home={sys.base_prefix}")
    lines.append(f"executable={sys.executable}")
    lines += [f"site={d}" for d in site_dirs()]
    return "\n".join(lines) + "\n"
