"""Build the native flavor of the three FMUs (``glider-cosim build --flavor native``).

The same models in C99 (``src/*/<component>_model.c``) behind the same FMI layer
(``src/fmi/fmi_layer.c``) as the Python flavor, with the native back end
(``src/fmi/backend_native.c``). The variables come from the Python slaves' tables:
:func:`vars_header` writes them as C (struct, value references, start values, ranges and
their wording), and the model description is the Python slave's own, so both flavors
declare the same variables.

Each FMU carries a binary for each platform of :data:`glider_fmi.toolchain.PLATFORMS`
(Linux x86_64 and aarch64 at glibc 2.17, Windows x86_64, macOS x86_64 and arm64), all
built here by zig's C compiler from PyPI unless ``--compiler`` names others (see
:data:`FMI2_DIRS` for FMI 2's folders; FMI 3 uses its platform tuples), and ``sources/``
with every C file, ``buildDescription.xml`` and ``<SourceFiles>``, so tools can rebuild it.
"""

from __future__ import annotations

import functools
import hashlib
import logging
import tempfile
import zipfile
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

import glider_fmi
from glider_fmi import toolchain

from .. import components as registry
from . import lsref, objects, osp, platforms, wasm
from .files import (  # noqa: F401 (same_sources re-exported)
    FLAVOR_FILE,
    build_progress,
    made_once,
    package_version,
    replacing,
    same_sources,
)
from .native_description import build_description, model_description
from .native_vars import NativeBuildError, make_vars_header, vars_header  # noqa: F401
from .platforms import binary_entries, zip_member

log = logging.getLogger(__name__)

#: resource naming the flavor of an FMU ("python" or "native")
#: resource holding the hash of the sources a native FMU was built from
NATIVE_HASH_FILE = "resources/glider_cosim_native.sha256"
#: resource listing the platforms a native FMU has binaries for, one a line
PLATFORMS_FILE = "resources/glider_cosim_platforms.txt"
#: flags of every native compile (the same on both platforms)
CFLAGS = (
    "-std=c99",
    "-O2",
    "-pedantic",
    "-Wall",
    "-Wextra",
    "-Werror=implicit-function-declaration",
    "-ffp-contract=off",
)
LINUX_FLAGS = ("-fPIC", "-shared", "-fvisibility=hidden")
WIN64_FLAGS = ("-shared", "-static-libgcc")
MINGW = "x86_64-w64-mingw32-gcc"

FMI_DIR = Path(glider_fmi.__file__).resolve().parent
#: the layer and the native back end, in every native FMU
LAYER_FILES = ("fmi_layer.h", "fmi_layer.c", "fmi2_layer.c", "native_model.h", "backend_native.c",
               "glider_fp.h")  # fmt: skip


@dataclass(frozen=True)
class NativeComponent:
    """A native FMU: its slave class (variables) and its C files (model + glue)."""

    name: str
    slave: str  # module:class of the Python slave that defines the variables
    files: tuple[Path, ...]  # C sources and headers, besides the layer

    def slave_class(self) -> type:
        module, _, cls = self.slave.partition(":")
        return getattr(__import__(module, fromlist=[cls]), cls)


#: every registered component with C sources (:mod:`glider_cosim.components`), in
#: registry order; one without has the Python flavor only
NATIVE_COMPONENTS: tuple[NativeComponent, ...] = tuple(
    NativeComponent(c.model, c.slave, c.c_sources) for c in registry.COMPONENTS if c.native
)


# ---------------------------------------------------------------- sources and hash
def source_files(c: NativeComponent, fmi: int = 2) -> list[Path]:
    """Every C file of the component's FMU (the layer with the front end of FMI ``fmi``,
    the back end, models, glue)."""
    layer = [FMI_DIR / (f"fmi{fmi}_layer.c" if f == "fmi2_layer.c" else f) for f in LAYER_FILES]
    return layer + list(dict.fromkeys(c.files))


def native_hash(c: NativeComponent, fmi: int = 2, chain: toolchain.Toolchain | None = None) -> str:
    """SHA-256 over the C sources, the generated variables, the flags, the compilers
    (``chain``, default :func:`glider_fmi.toolchain.select`), the version and the code
    that writes the model description (``slave_base.py``, ``derivatives.py``).

    Made once a process for the same files (their paths, modification times and sizes),
    and once within :func:`~glider_cosim.fmus.files.same_sources` (issue 48)."""
    return made_once(("native", c.name, fmi, chain), lambda: _native_hash(c, fmi, chain))


def _native_hash(c: NativeComponent, fmi: int, chain: toolchain.Toolchain | None) -> str:
    files = [FMI_DIR / w for w in ("slave_base.py", "derivatives.py")] + source_files(c, fmi)
    stamp = tuple((str(f), st.st_mtime_ns, st.st_size) for f in files for st in [f.stat()])
    parts = (
        vars_header(c),
        f"fmi{fmi}{wasm.fingerprint() if fmi == 3 else ''}",  # + the component
        " ".join((*CFLAGS, *LINUX_FLAGS, *WIN64_FLAGS)),
        toolchain.fingerprint(chain),
        package_version(),
        osp.fingerprint(),
    )
    return _native_digest(parts, stamp)


@functools.lru_cache(maxsize=64)
def _native_digest(parts: tuple[str, ...], stamp: tuple[tuple[str, int, int], ...]) -> str:
    """:func:`native_hash` of its ``parts`` and the files of ``stamp`` (the first two, the
    Python code that writes the model description, hashed after the variables)."""
    header, *rest = parts
    h = hashlib.sha256(header.encode())
    h.update(b"".join(Path(path).read_bytes() for path, _, _ in stamp[:2]))
    for text in rest:
        h.update(text.encode())
    for path, _, _ in stamp[2:]:
        h.update(Path(path).name.encode())
        h.update(Path(path).read_bytes())
    return h.hexdigest()


def is_current(
    fmu: Path,
    c: NativeComponent,
    fmi: int = 2,
    chain: toolchain.Toolchain | None = None,
    need: list[str] | None = None,
) -> bool:
    """True if ``fmu`` is a native FMU of FMI ``fmi`` built from the current sources (by
    the compilers of ``chain``) with a binary for each platform of ``need`` (default:
    every platform ``chain`` builds, :func:`wanted_platforms`)."""
    try:
        with zipfile.ZipFile(fmu) as z:
            if z.read(NATIVE_HASH_FILE).decode().strip() != native_hash(c, fmi, chain):
                return False
            # the LS-REF folder is checked apart: its data are not in native_hash, which
            # makes the model description's GUID
            if not lsref.is_current(z):
                return False
            has = set(z.read(PLATFORMS_FILE).decode().split())
        return has >= set(need if need is not None else wanted_platforms(chain, False))
    except (OSError, KeyError, zipfile.BadZipFile, toolchain.ToolchainError):
        return False


def built_platforms(fmu: Path) -> frozenset[str]:
    """The platforms a native FMU of ours has binaries for (empty: none recorded)."""
    try:
        with zipfile.ZipFile(fmu) as z:
            return frozenset(z.read(PLATFORMS_FILE).decode().split())
    except (OSError, KeyError, zipfile.BadZipFile):
        return frozenset()


def wanted_platforms(chain: toolchain.Toolchain | None, host_only: bool) -> list[str]:
    """The platforms a build makes: every one ``chain`` (default
    :func:`glider_fmi.toolchain.select`) builds; with ``host_only``, this machine's alone
    (every one when ``chain`` does not build this machine's)."""
    chain = chain or toolchain.select()
    every = [k for k in toolchain.PLATFORMS if chain.for_platform(k) is not None]
    host = toolchain.host_platform()
    return [host] if host_only and host in every else every


def holds_host_only(folder: Path, chain: toolchain.Toolchain | None = None) -> bool:
    """True if a native FMU of ours in ``folder`` has binaries for fewer platforms than a
    full build (a run's host-only set, :func:`build_native`)."""
    every = set(wanted_platforms(chain, False))
    for c in NATIVE_COMPONENTS:
        has = built_platforms(folder / f"{c.name}.fmu")
        if has and not has >= every:
            return True
    return False


# ---------------------------------------------------------------- building
def _package(c: NativeComponent, out: Path, chain: toolchain.Toolchain, fmi: int, src: Path,
             built: dict[str, Path], extra: dict[str, dict] | None = None) -> Path:  # fmt: skip
    """Write ``<out>/<name>.fmu``: the libraries ``built`` (platform key -> file), ``extra``."""
    own = {f.name for f in source_files(c, fmi)} | {f"{c.name}_vars.h"}
    files = sorted(src / n for n in own)
    c_names = [p.name for p in files if p.suffix == ".c"]
    out.mkdir(parents=True, exist_ok=True)
    fmu = out / f"{c.name}.fmu"
    md = model_description(c, c_names, native_hash(c, 2, chain))
    if fmi == 3:
        from .fmi3_description import fmi3_model_description

        md = fmi3_model_description(md)
    with replacing(fmu) as part, zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", md)
        z.writestr(osp.extra_path(md), osp.generate(md))
        for entry, data in lsref.entries(md).items():
            z.writestr(entry, data)
        mine = (extra or {}).get(c.name, {})  # zip path -> bytes: its component, manifest
        for entry, data in {**binary_entries(c.name, built, fmi), **mine}.items():
            z.writestr(zip_member(entry), data)
        for p in files:
            z.write(p, f"sources/{p.name}")
        z.writestr("sources/buildDescription.xml", build_description(c, c_names))
        z.writestr(FLAVOR_FILE, "native\n")
        z.writestr(NATIVE_HASH_FILE, native_hash(c, fmi, chain) + "\n")
        wasm_key = [wasm.WASM_PLATFORM] if mine else []
        z.writestr(PLATFORMS_FILE, "".join(f"{k}\n" for k in [*built, *wasm_key]))
    osp.write_beside(fmu)  # where OSP's tools look for it
    return fmu


def build_native_components(
    todo: list[NativeComponent],
    out: Path,
    chain: toolchain.Toolchain,
    fmi: int = 2,
    platforms: list[str] | None = None,
) -> dict[str, Path]:
    """Build the native FMUs ``todo`` of FMI ``fmi`` into ``out``, each with a binary for
    every platform of ``platforms`` (default: every one ``chain`` builds): model
    identifier -> path. The C files are compiled once per platform, in one pool with the
    links (:func:`glider_cosim.fmus.objects.build_binaries`)."""
    keys = [k for k in (platforms or toolchain.PLATFORMS) if chain.for_platform(k) is not None]
    if not keys:
        raise NativeBuildError(f"--compiler {chain.spec} builds no platform")
    targets = [objects.Target(k, toolchain.PLATFORMS[k], chain.for_platform(k)) for k in keys]
    with tempfile.TemporaryDirectory(prefix="glider_native_") as tmp, \
            build_progress(todo, "native", fmi, out, keys) as progress:  # fmt: skip
        stage = Path(tmp)
        src = staged_sources(fmi, chain, stage)
        sources = {c.name: [src / f.name for f in source_files(c, fmi)] for c in todo}
        try:
            built = objects.build_binaries(sources, targets, CFLAGS, stage, progress=progress)
        except toolchain.ToolchainError as err:
            raise NativeBuildError(str(err)) from None
        # FMI-LS-WASM: each FMU's component and manifest (WasmBuildError: a ToolchainError)
        extra = wasm.fmu_components(sources, stage, CFLAGS) if fmi == 3 else {}
        return {c.name: _package(c, out, chain, fmi, src, built[c.name], extra) for c in todo}


def staged_sources(fmi: int, chain: toolchain.Toolchain, fallback: Path) -> Path:
    """The sources of the three FMUs of FMI ``fmi``, staged once per content in the FMU
    cache (:func:`glider_cosim.fmus.platforms.stage`; each FMU's ``sources/`` is its
    part of them)."""
    digest = hashlib.sha256(
        "".join(native_hash(c, fmi, chain) for c in NATIVE_COMPONENTS).encode()
    ).hexdigest()
    files: dict[str, bytes] = {}
    for c in NATIVE_COMPONENTS:
        for f in source_files(c, fmi):
            files[f.name] = f.read_bytes()
        files[f"{c.name}_vars.h"] = vars_header(c).encode()
    return platforms.stage(f"fmi{fmi}-{digest[:16]}", files, fallback)


def missing_platforms(chain: toolchain.Toolchain) -> list[str]:
    """The platforms of :data:`glider_fmi.toolchain.PLATFORMS` that ``chain`` cannot build."""
    return [k for k in toolchain.PLATFORMS if chain.for_platform(k) is None]


def build_native(
    out: Path | str,
    only_stale: bool = False,
    fmi: int = 2,
    compiler: str | None = None,
    host_only: bool | None = None,
    names: Collection[str] | None = None,
    force: Collection[str] = (),
) -> dict[str, Path]:
    """Build the three native FMUs of FMI ``fmi`` (those of ``names`` if given) into
    ``out``; model identifier -> path. ``force``: those rebuilt even if current.

    ``compiler`` is ``--compiler`` (None: ``$GLIDER_COSIM_COMPILER``, else zig). When the
    compilers chosen cannot build some platforms (zig not installed), those are left out
    and a one-line warning names them. ``host_only``: True builds this machine's binary
    alone (a set to run here, never to hand out; a current full set is kept), False
    every platform's, None keeps what the FMUs in ``out`` hold with ``only_stale`` (a
    host-only set stays host-only), else every platform's.
    """
    out = Path(out)
    try:
        chain = toolchain.select(compiler)
    except toolchain.ToolchainError as err:
        raise NativeBuildError(str(err)) from None
    if host_only is None:
        host_only = only_stale and holds_host_only(out, chain)
    wanted = wanted_platforms(chain, host_only)
    chosen = [c for c in NATIVE_COMPONENTS if names is None or c.name in names]
    result = {c.name: out / f"{c.name}.fmu" for c in chosen}
    todo = [c for c in chosen if c.name in force
            or not (only_stale and is_current(result[c.name], c, fmi, chain, wanted))]  # fmt: skip
    if not todo:
        return result
    missing = missing_platforms(chain)
    if missing and not host_only:
        log.warning(
            "--compiler %s builds no %s: the native FMUs leave those out (zig, the "
            "default, builds every platform)",
            chain.spec,
            ", ".join(missing),
        )
    result.update(build_native_components(todo, out, chain, fmi, wanted))
    return result
