"""Build the three FMUs (``glider-cosim build``).

pythonfmu packages each slave (script, variables, modelDescription, resources); its
prebuilt binary is then replaced by our FMI runtime (:mod:`glider_fmi.compile`),
compiled here once per build, and the FMU records the Python that runtime starts in
hosts without one. FMUs carry a linux64 binary only: pythonfmu's win64 binary is left
out (see the README, "FMI runtime").
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import sys
import tempfile
import uuid
import zipfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import glider_controller
import glider_fmi
import glider_observer
import glider_plant
from glider_fmi import compile as runtime

from . import osp

#: resource file in each FMU holding the hash of the sources it was built from
HASH_FILE = "resources/glider_cosim_source.sha256"


@dataclass(frozen=True)
class Component:
    """An FMU: its model identifier and the packages it bundles (slave script first)."""

    name: str
    packages: tuple[Path, ...]

    @property
    def slave_module(self) -> str:
        """Module holding the slave class, e.g. ``glider_plant.slave``."""
        return f"{PACKAGE_NAMES[self.packages[0]]}.slave"

    @property
    def sources(self) -> list[Path]:
        return sorted(f for pkg in self.packages for f in pkg.glob("*.py"))


def _pkg(module) -> Path:
    return Path(module.__file__).resolve().parent


COMPONENTS: tuple[Component, ...] = (
    Component("GliderPlant", (_pkg(glider_plant), _pkg(glider_fmi))),
    Component("GliderObserver", (_pkg(glider_observer), _pkg(glider_plant), _pkg(glider_fmi))),
    Component("GliderController", (_pkg(glider_controller), _pkg(glider_plant), _pkg(glider_fmi))),
)
PACKAGE_NAMES = {
    _pkg(glider_plant): "glider_plant",
    _pkg(glider_observer): "glider_observer",
    _pkg(glider_controller): "glider_controller",
    _pkg(glider_fmi): "glider_fmi",
}
#: the FMU's binary for this platform (the only one it carries)
BINARY_DIR = "binaries/linux64"


def source_hash(c: Component) -> str:
    """SHA-256 over the component's sources, the script shim, the runtime (source and
    flags) and the Python configuration it records."""
    h = hashlib.sha256(shim_text(c).encode())
    h.update(runtime.runtime_fingerprint().encode())
    h.update(runtime.python_config().encode())
    h.update(osp.fingerprint().encode())
    for f in c.sources:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def shim_text(c: Component) -> str:
    """The FMU's script: it only imports the slave class (see build_component)."""
    return (
        f'"""pythonfmu entry point of {c.name}: the slave is {c.slave_module}."""\n\n'
        f'from {c.slave_module} import {c.name}\n\n__all__ = ["{c.name}"]\n'
    )


def is_current(fmu: Path, c: Component) -> bool:
    """True if ``fmu`` exists and was built from the current sources."""
    try:
        with zipfile.ZipFile(fmu) as z:
            return z.read(HASH_FILE).decode().strip() == source_hash(c)
    except (OSError, KeyError, zipfile.BadZipFile):
        return False


def _replace_binaries(fmu: Path, model_identifier: str, binary: Path) -> None:
    """Swap pythonfmu's binaries in ``fmu`` for our runtime (linux64 only)."""
    tmp = fmu.with_name(fmu.name + ".part")
    try:
        with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as dst:
            for item in src.infolist():
                if not item.filename.startswith("binaries/"):
                    dst.writestr(item, src.read(item))
            dst.write(binary, f"{BINARY_DIR}/{model_identifier}.so")
        tmp.replace(fmu)
    finally:
        tmp.unlink(missing_ok=True)


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


def package_slave(
    script: Path,
    out: Path,
    binary: Path,
    project_files: Sequence[Path] = (),
    **options: Any,
) -> Path:
    """Package a pythonfmu slave script as an FMU that runs on our FMI runtime.

    Parameters
    ----------
    script : Path
        The pythonfmu script; its slave class must be named like the script (the model
        identifier).
    out : Path
        Folder the ``.fmu`` is written to.
    binary : Path
        The compiled runtime (:func:`glider_fmi.compile.compile_runtime`).
    project_files : sequence of Path
        Further files and package folders for ``resources/``.
    **options
        pythonfmu's capability flags, e.g. ``canGetAndSetFMUstate=True``.

    Returns
    -------
    Path
        The ``.fmu``.
    """
    from pythonfmu.builder import FmuBuilder

    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="glider_fmi_cfg_") as tmp:
        config = Path(tmp) / runtime.PYTHON_CONFIG_FILE
        config.write_text(runtime.python_config())
        staged = Path(
            FmuBuilder.build_FMU(
                script, dest=Path(tmp), project_files=[*project_files, config], **options
            )
        )
        _replace_binaries(staged, staged.stem, binary)
        osp.add_to_fmu(staged)
        fmu = out / staged.name
        with replacing(fmu) as part:  # a process reading the FMU meanwhile sees old or new
            shutil.copyfile(staged, part)
    osp.write_beside(fmu)  # where OSP's tools look for it
    return fmu


def build_slave_fmu(
    script: Path | str, out: Path | str, project_files: Sequence[Path] = ()
) -> Path:
    """Compile the runtime and package one pythonfmu script with it (tests, users' slaves).

    Returns
    -------
    Path
        The ``.fmu`` in ``out``.
    """
    with tempfile.TemporaryDirectory(prefix="glider_fmi_") as tmp:
        binary = Path(tmp) / "glider_fmi_runtime.so"
        runtime.compile_runtime(binary)
        return package_slave(Path(script), Path(out), binary, project_files)


def build_component(c: Component, out: Path, binary: Path) -> Path:
    """Build one FMU into ``out`` with the compiled runtime ``binary``; return its path."""
    with tempfile.TemporaryDirectory(prefix=f"{c.name}_") as tmp:
        stage = Path(tmp)
        # The FMU's script is a shim that imports the slave class; its name is the model
        # identifier, unique per FMU. The runtime imports it once per process.
        script = stage / f"{c.name}.py"
        script.write_text(shim_text(c))
        project = []
        for pkg in c.packages:
            dst = stage / PACKAGE_NAMES[pkg]
            ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.c", "*.h", "*.so")
            shutil.copytree(pkg, dst, ignore=ignore)
            project.append(dst)
        (stage / "glider_cosim_source.sha256").write_text(source_hash(c) + "\n")
        project.append(stage / "glider_cosim_source.sha256")
        (stage / "glider_cosim_flavor.txt").write_text("python\n")
        project.append(stage / "glider_cosim_flavor.txt")
        return package_slave(
            script, out, binary, project, canGetAndSetFMUstate=True, canSerializeFMUstate=True
        )


#: the flavors of our FMUs: the Python reference (default) and the native C99 build
FLAVORS = ("python", "native")
#: where ``glider-cosim build`` writes each flavor unless ``--out`` is given (the
#: project's export folder); runs use the per-user cache instead (:func:`cache_dir`)
DEFAULT_DIRS = {"python": Path("fmus"), "native": Path("fmus") / "native"}
#: environment variable naming the cache folder (default: :func:`cache_root`)
CACHE_ENV = "GLIDER_COSIM_CACHE"


def cache_root() -> Path:
    """The per-user cache of built FMUs: ``$GLIDER_COSIM_CACHE`` if set, else
    ``$XDG_CACHE_HOME/glider-cosim`` (an absolute ``XDG_CACHE_HOME``), else the
    platform's cache folder: ``~/.cache`` on Linux, ``~/Library/Caches`` on macOS,
    ``%LOCALAPPDATA%`` on Windows."""
    own = os.environ.get(CACHE_ENV)
    if own:
        return Path(own)
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg and os.path.isabs(xdg):
        base = Path(xdg)
    elif sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    else:
        base = Path.home() / ".cache"
    return base / "glider-cosim"


def sources_key(flavor: str = "python") -> str:
    """A short hash over the sources of the flavor's three FMUs (each FMU's own hash,
    :func:`source_hash` or :func:`glider_cosim.native.native_hash`)."""
    if flavor == "native":
        from .native import NATIVE_COMPONENTS, native_hash

        hashes = [native_hash(c) for c in NATIVE_COMPONENTS]
    else:
        hashes = [source_hash(c) for c in COMPONENTS]
    return hashlib.sha256("\n".join(hashes).encode()).hexdigest()[:16]


def cache_dir(flavor: str = "python", fmi: int = 2) -> Path:
    """The cache folder of the flavor's FMUs (of FMI ``fmi``) built from the current
    sources: ``<cache_root>/<version>/<flavor>[-fmi3]-<sources_key>``. Other sources
    (another checkout, an edit) get another folder, so the FMUs are rebuilt when stale."""
    from .native import _version

    if flavor not in FLAVORS:
        raise ValueError(f"flavor {flavor!r} is invalid: expected one of {', '.join(FLAVORS)}")
    kind = flavor if fmi == 2 else f"{flavor}-fmi{fmi}"
    return cache_root() / _version() / f"{kind}-{sources_key(flavor)}"


def fmu_folder(fmu_dir: str | Path | None, flavor: str | None = None) -> Path:
    """``fmu_dir`` as a path; None is the cache folder of ``flavor`` (python if None)."""
    return Path(fmu_dir) if fmu_dir is not None else cache_dir(flavor or "python")


#: the FMI versions we build (``--fmi``)
FMI_VERSIONS = (2, 3)
#: where each flavor's FMI 3.0 FMUs are built unless a folder is given
DEFAULT_DIRS_FMI3 = {"python": Path("fmus") / "fmi3", "native": Path("fmus") / "fmi3" / "native"}


def default_dir(flavor: str | None = None, fmi: int | None = None) -> Path:
    """The folder a flavor (python if None) of FMI ``fmi`` (2 if None) is built in."""
    return (DEFAULT_DIRS_FMI3 if fmi == 3 else DEFAULT_DIRS)[flavor or "python"]


def fmu_fmi_version(fmu: Path | str) -> int | None:
    """The FMI version (2 or 3) an FMU's model description declares, None if unreadable."""
    import re

    try:
        with zipfile.ZipFile(fmu) as z, z.open("modelDescription.xml") as f:
            head = f.read(4096).decode("utf-8", "replace")
    except (OSError, KeyError, zipfile.BadZipFile):
        return None
    m = re.search(r'fmiVersion\s*=\s*"([23])\.', head)
    return int(m.group(1)) if m else None


def folder_fmi(folder: Path | str) -> int | None:
    """The FMI version of the FMUs of ours in ``folder`` (the first found), or None."""
    for c in COMPONENTS:
        found = fmu_fmi_version(Path(folder) / f"{c.name}.fmu")
        if found:
            return found
    return None


def folder_flavor(folder: Path | str) -> str | None:
    """The flavor the FMUs in ``folder`` record (the first of ours found), or None."""
    from .native import fmu_flavor

    for c in COMPONENTS:
        found = fmu_flavor(Path(folder) / f"{c.name}.fmu")
        if found:
            return found
    return None


def build_all(
    out: Path | str = "fmus",
    only_stale: bool = False,
    flavor: str | None = None,
    fmi: int | None = None,
) -> dict[str, Path]:
    """Build GliderPlant, GliderObserver and GliderController into ``out``.

    Parameters
    ----------
    out : path
        Output folder (created if missing).
    only_stale : bool
        Rebuild only FMUs that are missing or were built from other sources.
    flavor : {"python", "native"} or None
        Which build: None keeps the flavor the FMUs already in ``out`` record (so a folder
        of native FMUs is never rebuilt as Python ones), Python if there are none.
    fmi : {2, 3} or None
        FMI version: None keeps the one the FMUs already in ``out`` declare (a folder of
        FMI 3.0 FMUs stays FMI 3.0), 2 if there are none.

    Returns
    -------
    dict
        Model identifier -> path of the ``.fmu``.
    """
    out = Path(out)
    if flavor is None:
        flavor = folder_flavor(out) or "python"
    if flavor not in FLAVORS:
        raise ValueError(f"flavor {flavor!r} is invalid: expected one of {', '.join(FLAVORS)}")
    if fmi is None:
        fmi = folder_fmi(out) or 2
    if fmi not in FMI_VERSIONS:
        raise ValueError(f"FMI version {fmi!r} is invalid: expected 2 or 3")
    if fmi == 3:
        from .fmi3 import build_fmi3

        return build_fmi3(out, flavor, only_stale)
    if only_stale and any(fmu_fmi_version(out / f"{c.name}.fmu") == 3 for c in COMPONENTS):
        only_stale = False  # FMI 3.0 FMUs (which keep the FMI 2.0 build's hash) to replace
    if flavor == "native":
        from .native import build_native

        return _with_osp(build_native(out, only_stale))
    todo = [c for c in COMPONENTS if not (only_stale and is_current(out / f"{c.name}.fmu", c))]
    result = {c.name: out / f"{c.name}.fmu" for c in COMPONENTS}
    if todo:
        with tempfile.TemporaryDirectory(prefix="glider_fmi_") as tmp:
            binary = Path(tmp) / "glider_fmi_runtime.so"
            runtime.compile_runtime(binary)
            for c in todo:
                result[c.name] = build_component(c, out, binary)
    return _with_osp(result)


def _with_osp(fmus: dict[str, Path]) -> dict[str, Path]:
    """Write each FMU's OSP-IS description beside it (also for FMUs not rebuilt)."""
    for fmu in fmus.values():
        osp.write_beside(fmu)
    return fmus


def add_fmu_options(parser: Any, fmi: bool = False) -> None:
    """``--fmu-dir`` and ``--flavor`` on a command that runs our FMUs (and ``--fmi``
    with ``fmi``)."""
    parser.add_argument(
        "--fmu-dir",
        default=None,
        help="FMU folder, built if missing or stale in the flavor it holds (default: the "
        "per-user cache, e.g. ~/.cache/glider-cosim, built from the installed sources)",
    )
    parser.add_argument(
        "--flavor",
        choices=FLAVORS,
        default=None,
        help="which FMUs: the Python reference or the native C99 build (default: the "
        "flavor the FMU folder holds, python if it is empty)",
    )
    if fmi:
        parser.add_argument(
            "--fmi",
            type=int,
            choices=FMI_VERSIONS,
            default=None,
            help="FMI version of our FMUs (default: the one the FMU folder holds, 2 if it is "
            "empty; FMI 3 FMUs are built in fmus/fmi3, fmus/fmi3/native)",
        )


def prepare_fmus(fmu_dir: str | Path | None, flavor: str | None, fmi: int | None = None) -> Path:
    """The FMU folder a command's ``--fmu-dir``/``--flavor``/``--fmi`` name. Without a
    folder: the per-user cache's (:func:`cache_dir`), built there first if missing or
    stale. With a folder and ``--flavor`` or ``--fmi``: the FMUs there are built in that
    flavor and FMI version first if missing, stale or of another flavor or version."""
    if fmu_dir is None:
        flavor = flavor or "python"
        folder = cache_dir(flavor, fmi or 2)
        build_all(folder, only_stale=True, flavor=flavor, fmi=fmi or 2)
        return folder
    folder = Path(fmu_dir)
    if flavor is not None or fmi is not None:
        build_all(folder, only_stale=True, flavor=flavor, fmi=fmi)
    return folder
