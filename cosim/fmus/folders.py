"""Where the FMUs live (the per-user cache, an export folder) and building the set a run needs."""

from __future__ import annotations

import hashlib
import tempfile
import zipfile
from pathlib import Path

from glider_fmi import compile as runtime
from glider_fmi.toolchain import host_platform

from . import osp
from .files import CACHE_ENV, cache_root, fmu_flavor, package_version  # noqa: F401 (re-exported)
from .fmi3 import build_fmi3
from .native import NATIVE_COMPONENTS, build_native, native_hash
from .options import FLAVORS, FMI_VERSIONS, add_fmu_options  # noqa: F401 (re-exported)
from .python import (
    COMPONENTS,
    DEFAULT_DIRS_FMI3,
    build_component,
    is_current,
    source_hash,
)

#: the infix of a host-only set's cache folder (:func:`cache_dir`)
HOST_ONLY = "-only-"

#: where ``glider-cosim build`` writes each flavor unless ``--out`` is given (the
#: project's export folder); runs use the per-user cache instead (:func:`cache_dir`)
DEFAULT_DIRS = {"python": Path("fmus"), "native": Path("fmus") / "native"}


def sources_key(flavor: str = "python") -> str:
    """A short hash over the sources of the flavor's three FMUs (each FMU's own hash,
    :func:`source_hash` or :func:`glider_cosim.fmus.native.native_hash`)."""
    if flavor == "native":
        hashes = [native_hash(c) for c in NATIVE_COMPONENTS]
    else:
        hashes = [source_hash(c) for c in COMPONENTS]
    return hashlib.sha256("\n".join(hashes).encode()).hexdigest()[:16]


def cache_dir(flavor: str = "python", fmi: int = 2, host_only: bool = False) -> Path:
    """The cache folder of the flavor's FMUs (of FMI ``fmi``) built from the current
    sources: ``<cache_root>/<version>/<flavor>[-fmi3]-<sources_key>``. Other sources
    (another checkout, an edit) get another folder, so the FMUs are rebuilt when stale.

    ``host_only`` (native flavor): the folder of the set built to run on this machine
    alone, ``<flavor>[-fmi3]-only-<platform>-<sources_key>`` (:data:`HOST_ONLY`), apart
    from the full set so that it is never taken for one."""

    if flavor not in FLAVORS:
        raise ValueError(f"flavor {flavor!r} is invalid: expected one of {', '.join(FLAVORS)}")
    kind = flavor if fmi == 2 else f"{flavor}-fmi{fmi}"
    if host_only and flavor == "native":
        kind += f"{HOST_ONLY}{host_platform()}"
    return cache_root() / package_version() / f"{kind}-{sources_key(flavor)}"


def fmu_folder(fmu_dir: str | Path | None, flavor: str | None = None) -> Path:
    """``fmu_dir`` as a path; None is the cache folder of ``flavor`` (python if None)."""
    return Path(fmu_dir) if fmu_dir is not None else cache_dir(flavor or "python")


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
    host_only: bool | None = None,
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
    host_only : bool or None
        Native flavor: True builds this machine's binary alone (a set to run here; a
        current full set is kept), False every platform's (a set to hand out: exports),
        None keeps what the FMUs in ``out`` hold with ``only_stale``, else every
        platform's (:func:`glider_cosim.fmus.native.build_native`).

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
        return build_fmi3(out, flavor, only_stale, host_only)
    if only_stale and any(fmu_fmi_version(out / f"{c.name}.fmu") == 3 for c in COMPONENTS):
        only_stale = False  # FMI 3.0 FMUs (which keep the FMI 2.0 build's hash) to replace
    if flavor == "native":
        return _with_osp(build_native(out, only_stale, host_only=host_only))
    todo = [c for c in COMPONENTS if not (only_stale and is_current(out / f"{c.name}.fmu", c))]
    result = {c.name: out / f"{c.name}.fmu" for c in COMPONENTS}
    if todo:
        with tempfile.TemporaryDirectory(prefix="glider_fmi_") as tmp:
            binary = runtime.compile_runtimes(tmp)
            for c in todo:
                result[c.name] = build_component(c, out, binary)
    return _with_osp(result)


def _with_osp(fmus: dict[str, Path]) -> dict[str, Path]:
    """Write each FMU's OSP-IS description beside it (also for FMUs not rebuilt)."""
    for fmu in fmus.values():
        osp.write_beside(fmu)
    return fmus


def prepare_fmus(
    fmu_dir: str | Path | None,
    flavor: str | None,
    fmi: int | None = None,
    host_only: bool = False,
) -> Path:
    """The FMU folder a command's ``--fmu-dir``/``--flavor``/``--fmi`` name. Without a
    folder: the per-user cache's (:func:`cache_dir`), built there first if missing or
    stale. With a folder and ``--flavor`` or ``--fmi``: the FMUs there are built in that
    flavor and FMI version first if missing, stale or of another flavor or version.

    ``host_only``: the FMUs are run on this machine and nowhere else (a run, a local
    sweep): from the cache, the native flavor's full set if it is current, else a set
    with this machine's binary alone, built in its own folder (``cache_dir(...,
    host_only=True)``). Whatever hands FMUs on (exports) keeps the default, False:
    every platform's binary. A folder given is built with every platform's binary (its
    FMUs may be handed on), or kept host-only if it holds a host-only set."""
    if fmu_dir is None:
        flavor = flavor or "python"
        folder = cache_dir(flavor, fmi or 2)
        if host_only and flavor == "native" and not _current_native(folder, fmi or 2):
            folder = cache_dir(flavor, fmi or 2, host_only=True)
        build_all(folder, only_stale=True, flavor=flavor, fmi=fmi or 2, host_only=host_only)
        return folder
    folder = Path(fmu_dir)
    if flavor is not None or fmi is not None:
        build_all(folder, only_stale=True, flavor=flavor, fmi=fmi)  # kept as it is
    return folder


def _current_native(folder: Path, fmi: int) -> bool:
    """True if ``folder`` holds the full native set of FMI ``fmi``, current."""
    from .native import is_current

    return all(is_current(folder / f"{c.name}.fmu", c, fmi) for c in NATIVE_COMPONENTS)
