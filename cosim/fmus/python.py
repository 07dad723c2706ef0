"""Build the Python flavor: a pythonfmu slave packaged with our FMI layer's runtime."""

from __future__ import annotations

import hashlib
import shutil
import tempfile
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from glider_fmi import bundle
from glider_fmi import compile as runtime

from .. import components as registry
from . import lsref, osp
from .files import made_once, replacing

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


#: every registered component's Python FMU (:mod:`glider_cosim.components`), in
#: registry order: its model name and the packages it bundles
COMPONENTS: tuple[Component, ...] = tuple(
    Component(c.model, tuple(folder for _, folder in registry.bundled(c)))
    for c in registry.COMPONENTS
)


#: package folder -> import name, of every package an FMU bundles
PACKAGE_NAMES = {folder: name for c in registry.COMPONENTS for name, folder in registry.bundled(c)}


#: the FMU's binary folder per platform of the runtime (FMI 2: ``linux64`` and, with no
#: standard name, ``aarch64-linux``)
BINARY_DIRS = {"x86_64-linux": "binaries/linux64", "aarch64-linux": "binaries/aarch64-linux"}
BINARY_DIR = BINARY_DIRS["x86_64-linux"]


def _binaries(binary: Path | dict[str, Path]) -> dict[str, Path]:
    """Platform -> runtime library: one Path is the x86_64 Linux one."""
    return binary if isinstance(binary, dict) else {"x86_64-linux": Path(binary)}


def source_hash(c: Component) -> str:
    """SHA-256 over the component's sources, the script shim, the runtime (source and
    flags) and the Python configuration it records (made once within
    :func:`~glider_cosim.fmus.files.same_sources`)."""
    return made_once(("python", c.name), lambda: _source_hash(c))


def _source_hash(c: Component) -> str:
    h = hashlib.sha256(shim_text(c).encode())
    h.update(runtime.runtime_fingerprint().encode())
    h.update(runtime.python_config().encode())
    h.update(osp.fingerprint().encode())
    h.update(lsref.fingerprint().encode())
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


def _finish(fmu: Path, model_identifier: str, binary: Path | dict[str, Path]) -> None:
    """Make pythonfmu's ``fmu`` ours: its binaries swapped for our runtime (one per
    platform built) and its bundled imports made relative
    (:func:`glider_fmi.bundle.relativize_bundle`), so that the FMU runs only the code in
    its own ``resources/``."""
    tmp = fmu.with_name(fmu.name + ".part")
    try:
        with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as dst:
            items = [i for i in src.infolist() if not i.filename.startswith("binaries/")]
            data = {i.filename: src.read(i) for i in items}
            res = {n.removeprefix("resources/"): d for n, d in data.items()
                   if n.startswith("resources/") and not n.endswith("/")}  # fmt: skip
            data.update({f"resources/{n}": d for n, d in bundle.relativize_bundle(res).items()})
            for item in items:
                dst.writestr(item, data[item.filename])
            for platform, lib in _binaries(binary).items():
                dst.write(lib, f"{BINARY_DIRS[platform]}/{model_identifier}.so")
        tmp.replace(fmu)
    finally:
        tmp.unlink(missing_ok=True)


def package_slave(
    script: Path,
    out: Path,
    binary: Path | dict[str, Path],
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
    binary : Path or dict
        The compiled runtime (:func:`glider_fmi.compile.compile_runtime`), or one per
        platform (:func:`glider_fmi.compile.compile_runtimes`).
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
        _finish(staged, staged.stem, binary)
        osp.add_to_fmu(staged)
        lsref.add_to_fmu(staged)  # our models' experiments (none for another model)
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
        binaries = runtime.compile_runtimes(tmp)
        return package_slave(Path(script), Path(out), binaries, project_files)


def shown_runtimes(
    folder: Path | str,
    progress: Any,
    fmi3: bool = False,
    platforms: Sequence[str] = runtime.PYTHON_PLATFORMS,
) -> dict[str, Path]:
    """:func:`glider_fmi.compile.compile_runtimes` for ``platforms``, a step of
    ``progress`` (:func:`~glider_cosim.fmus.files.build_progress`), with zig's one-time
    build of each platform's C runtime named first
    (:func:`~glider_cosim.fmus.objects.zig_first_note`)."""
    from glider_fmi import toolchain

    from .objects import Target, zig_first_note

    try:
        chain = toolchain.select()
    except toolchain.ToolchainError:
        chain = None  # compile_runtimes says what is wrong
    keys = [k for k in platforms if chain and chain.for_platform(k)]
    for k in keys:
        note = zig_first_note(Target(k, toolchain.PLATFORMS[k], chain.for_platform(k)))
        if note:
            progress.note(note)
    progress.step(f"compiling the FMI {3 if fmi3 else 2}.0 runtime for {' and '.join(keys)}")
    return runtime.compile_runtimes(folder, fmi3=fmi3, chain=chain, platforms=platforms)


def build_component(c: Component, out: Path, binary: Path | dict[str, Path]) -> Path:
    """Build one FMU into ``out`` with the compiled runtime ``binary`` (one per platform);
    return its path."""
    with tempfile.TemporaryDirectory(prefix=f"{c.name}_") as tmp:
        stage = Path(tmp)
        # The FMU's script is a shim that imports the slave class; its name is the model
        # identifier, unique per FMU. The runtime imports it once per process.
        script = stage / f"{c.name}.py"
        script.write_text(shim_text(c))
        project = []
        for pkg in c.packages:
            dst = stage / PACKAGE_NAMES[pkg]
            # its LS-REF folder goes to extra/ (lsref.add_to_fmu), not with the modules
            ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.c", "*.h", "*.so", "lsref")
            shutil.copytree(pkg, dst, ignore=ignore)
            project.append(dst)
        (stage / "glider_cosim_source.sha256").write_text(source_hash(c) + "\n")
        project.append(stage / "glider_cosim_source.sha256")
        (stage / "glider_cosim_flavor.txt").write_text("python\n")
        project.append(stage / "glider_cosim_flavor.txt")
        return package_slave(
            script, out, binary, project, canGetAndSetFMUstate=True, canSerializeFMUstate=True
        )


#: where each flavor's FMI 3.0 FMUs are built unless a folder is given
DEFAULT_DIRS_FMI3 = {"python": Path("fmus") / "fmi3", "native": Path("fmus") / "fmi3" / "native"}
