"""Where the FMUs live (the per-user cache, an export folder) and building the set a run needs."""

from __future__ import annotations

import hashlib
import logging
import tempfile
import zipfile
from collections.abc import Collection
from pathlib import Path

from glider_fmi.compile import PYTHON_PLATFORMS
from glider_fmi.toolchain import host_platform

from ..inputs.text import quote
from . import lsref, osp, record
from .files import (  # noqa: F401 (re-exported)
    CACHE_ENV,
    build_progress,
    cache_root,
    file_sha256,
    fmu_flavor,
    package_version,
    same_sources,
)
from .fmi3 import build_fmi3
from .native import NATIVE_COMPONENTS, build_native, native_hash
from .options import FLAVORS, FMI_VERSIONS  # noqa: F401 (re-exported)
from .python import (
    COMPONENTS,
    DEFAULT_DIRS_FMI3,
    build_component,
    is_current,
    shown_runtimes,
    source_hash,
)
from .record import FmuFolderError  # noqa: F401 (re-exported)

log = logging.getLogger(__name__)

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
    hashes.append(lsref.fingerprint())  # the experiments the FMUs carry
    return hashlib.sha256("\n".join(hashes).encode()).hexdigest()[:16]


def cache_dir(flavor: str = "python", fmi: int = 2, host_only: bool = False) -> Path:
    """The cache folder of the flavor's FMUs (of FMI ``fmi``) built from the current
    sources: ``<cache_root>/<version>/<flavor>[-fmi3]-<sources_key>``. Other sources
    (another checkout, an edit) get another folder, so the FMUs are rebuilt when stale.

    ``host_only`` (the native flavor, the Python flavor's FMI 2.0 set): the folder of the
    set built to run on this machine alone, ``<flavor>[-fmi3]-only-<platform>-<sources_key>``
    (:data:`HOST_ONLY`), apart from the full set so that it is never taken for one."""

    if flavor not in FLAVORS:
        raise ValueError(f"flavor {flavor!r} is invalid: expected one of {', '.join(FLAVORS)}")
    kind = flavor if fmi == 2 else f"{flavor}-fmi{fmi}"
    if host_only and _has_host_only(flavor, fmi):
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
    *,
    overwrite: bool = False,
    skip: Collection[str] = (),
    option: str = "--fmu-dir",
) -> dict[str, Path]:
    """Build GliderPlant, GliderObserver and GliderController into ``out``.

    Nothing of the user's is written over (:mod:`glider_cosim.fmus.record`): the folder's
    record ``.glider-cosim-fmus.json`` names the files glider-cosim built there, with
    their SHA-256; a file under one of our names that is not in it (foreign), differs from
    it (changed) or is no FMU (corrupt), and a set of ours of another flavor or FMI
    version than ``flavor``/``fmi``, are refused unless ``overwrite``. The record is
    written after each build. In the per-user cache (glider-cosim's own) such a file is
    replaced, with a warning.

    Parameters
    ----------
    out : path
        Output folder (created if missing).
    only_stale : bool
        Rebuild only FMUs that are missing or were built from other sources.
    flavor : {"python", "native"} or None
        Which build: None keeps the flavor the FMUs of ours in ``out`` record (so a
        folder of native FMUs is never rebuilt as Python ones), Python if there are none.
    fmi : {2, 3} or None
        FMI version: None keeps the one the FMUs of ours in ``out`` declare (a folder of
        FMI 3.0 FMUs stays FMI 3.0), 2 if there are none.
    host_only : bool or None
        Native flavor: True builds this machine's binary alone (a set to run here; a
        current full set is kept), False every platform's (a set to hand out: exports),
        None keeps what the FMUs in ``out`` hold with ``only_stale``, else every
        platform's (:func:`glider_cosim.fmus.native.build_native`).
    overwrite : bool
        Replace foreign, changed and corrupt files under our names, and a set of another
        flavor or FMI version (``--overwrite-fmus``).
    skip : collection of str
        Model identifiers of ours neither built nor checked: the ones a scenario's
        ``[fmus]`` table swaps (a user's FMU named like ours stays as it is).
    option : str
        The option that named ``out``, for the messages (``--fmu-dir``, ``--out``).

    Returns
    -------
    dict
        Model identifier -> path of the ``.fmu`` (those not skipped).

    Raises
    ------
    FmuFolderError
        A file under one of our names is not ours, or the set is of another flavor or
        FMI version (one line naming the file and what to do).
    """
    out = Path(out)
    if flavor is not None and flavor not in FLAVORS:
        raise ValueError(f"flavor {flavor!r} is invalid: expected one of {', '.join(FLAVORS)}")
    if fmi is not None and fmi not in FMI_VERSIONS:
        raise ValueError(f"FMI version {fmi!r} is invalid: expected 2 or 3")
    names = [c.name for c in COMPONENTS if c.name not in skip]
    if not names:
        return {}
    with record.locked(out):
        trusted = in_cache(out)
        try:
            rec = record.read_record(out, option)
        except FmuFolderError:
            if not (overwrite or trusted):
                raise
            rec = {}
        held = record.survey(out, [f"{n}.fmu" for n in names], rec)
        force: set[str] = set()  # rebuilt even if current: what was not ours
        for h in held.values():
            if h.state in ("foreign", "changed", "corrupt"):
                if not (overwrite or trusted):
                    raise FmuFolderError(record.refusal(out, h, option))
                if trusted:
                    log.warning(f"{quote(str(out / h.name))}: not the file glider-cosim built in "
                                f"its cache ({h.state}): rebuilt")  # fmt: skip
                # replaced by ours, as asked (or in the cache), in one step when its build
                # is done (files.replacing): kept if the build fails; an OSP-IS file is
                # rewritten beside its FMU (_with_osp)
                if h.name.endswith(".fmu"):
                    force.add(h.name.removesuffix(".fmu"))
        ours = [h for h in held.values() if h.state == "ours" and h.name.endswith(".fmu")]
        flavor = flavor or next((h.flavor for h in ours if h.flavor), None) or "python"
        fmi = fmi or next((h.fmi for h in ours if h.fmi), None) or 2
        other = [h for h in ours if (h.flavor, h.fmi) != (flavor, fmi)]
        if other and not (overwrite or trusted):
            shown = ", ".join(h.name for h in other)
            held_set = record.describe_set(other[0].flavor, other[0].fmi)
            raise FmuFolderError(
                f"{option} {quote(str(out))} holds {held_set} "
                f"FMUs ({shown}), not the {record.describe_set(flavor, fmi)} ones asked for: a set "
                "is not converted in place; use another folder"
                + (" (or none: the per-user cache)" if option == "--fmu-dir" else "")
                + f" or pass {record.OVERWRITE_FLAG} to rebuild them there"
            )
        built = _build(out, only_stale, flavor, fmi, host_only, names, force)
        _update_record(out, names, held, rec)
        return built


def build(
    out: str | Path | None = None,
    *,
    flavor: str = "python",
    fmi: int = 2,
    compiler: str | None = None,
    overwrite_fmus: bool = False,
) -> dict[str, Path]:
    """Build our three FMUs into a folder: what ``glider-cosim build`` does.

    Parameters
    ----------
    out : path, optional
        The folder (default: :func:`default_dir` of the flavor and FMI version), checked
        before anything is built.
    flavor : {"python", "native"}
        The Python reference or the native C99 build.
    fmi : {2, 3}
        The FMI version.
    compiler : str, optional
        ``CC[,CC...]``: the C compilers (zig or system ones), for every build step and
        hash of this process (``$GLIDER_COSIM_COMPILER``; default: its value, else zig).
    overwrite_fmus : bool
        Replace what ``out`` holds under our FMUs' names.

    Returns
    -------
    dict
        Model name -> the FMU built.

    Raises
    ------
    UsageError
        ``out`` cannot be written, or a compiler chosen is missing or failed (one line
        naming the option).
    """
    import os

    from glider_fmi.toolchain import COMPILER_ENV, ToolchainError

    from ..inputs.outputs import UsageError, check_out_dir, os_error

    folder = Path(out) if out is not None else default_dir(flavor, fmi)
    check_out_dir(folder, "--out")
    if compiler is not None:  # every build step and hash of this process uses it
        os.environ[COMPILER_ENV] = compiler
    try:
        return build_all(folder, flavor=flavor, fmi=fmi, overwrite=overwrite_fmus, option="--out")
    except ToolchainError as err:  # a compiler chosen is missing or failed
        raise UsageError(str(err)) from None
    except OSError as err:
        raise os_error(err, {"--out": folder}) from None


def _build(
    out: Path,
    only_stale: bool,
    flavor: str,
    fmi: int,
    host_only: bool | None,
    names: list[str],
    force: set[str],
) -> dict[str, Path]:
    """:func:`build_all`'s build, once the folder is checked: the FMUs ``names``
    (``force``: rebuilt even if current)."""
    if fmi == 3:
        return _with_osp(build_fmi3(out, flavor, only_stale, host_only, names, force))
    if only_stale and any(fmu_fmi_version(out / f"{n}.fmu") == 3 for n in names):
        only_stale = False  # FMI 3.0 FMUs (which keep the FMI 2.0 build's hash) to replace
    if flavor == "native":
        return _with_osp(build_native(out, only_stale, 2, None, host_only, names, force))
    wanted = [c for c in COMPONENTS if c.name in names]
    stale = [c for c in wanted if not (only_stale and is_current(out / f"{c.name}.fmu", c))]
    todo = [c for c in wanted if c.name in force or c in stale]
    result = {c.name: out / f"{c.name}.fmu" for c in wanted}
    # this machine's runtime alone for a run's host-only set (prepare_fmus), else every one
    here = host_platform() if host_only and _has_host_only(flavor, 2) else None
    platforms = (here,) if here else PYTHON_PLATFORMS
    if todo:
        with tempfile.TemporaryDirectory(prefix="glider_fmi_") as tmp, \
                build_progress(todo, "python", 2, out, platforms) as progress:  # fmt: skip
            progress.set_total(1 + len(todo))
            binary = shown_runtimes(tmp, progress, platforms=platforms)
            for c in todo:
                progress.step(f"building {c.name}.fmu python")
                result[c.name] = build_component(c, out, binary)
    return _with_osp(result)


def _update_record(
    out: Path, names: list[str], held: dict[str, record.Held], rec: dict[str, dict] | None
) -> None:
    """Write ``out``'s record after a build: every file of ours there with its SHA-256
    (a folder without a record gets one when something was written in it)."""
    files = {k: v for k, v in (rec or {}).items() if (out / k).is_file()}
    written = False
    for n in names:
        for fname in (f"{n}.fmu", record.osp_name(f"{n}.fmu")):
            path = out / fname
            if not path.is_file():
                files.pop(fname, None)
                continue
            sha = file_sha256(path)
            written |= sha != held[fname].sha256
            old = files.get(fname)
            files[fname] = old if old and old["sha256"] == sha else record.entry_for(path)
    if written or (rec is not None and files != rec):
        record.write_record(out, files)


def in_cache(folder: Path | str) -> bool:
    """True if ``folder`` is in the per-user cache (:func:`cache_root`)."""
    try:
        return Path(folder).resolve().is_relative_to(cache_root().resolve())
    except OSError:
        return False


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
    *,
    overwrite: bool = False,
    skip: Collection[str] = (),
) -> Path:
    """The FMU folder a command's ``--fmu-dir``/``--flavor``/``--fmi`` name. Without a
    folder: the per-user cache's (:func:`cache_dir`), built there first if missing or
    stale. With a folder and ``--flavor`` or ``--fmi``: the FMUs there are built in that
    flavor and FMI version first if missing or stale; a set of another flavor or version,
    or a file there not built by glider-cosim, is refused (:func:`build_all`) unless
    ``overwrite`` (``--overwrite-fmus``: then they are replaced, the folder's flavor and
    version kept if none is given). ``skip``: our FMUs the command does not take from
    the folder (a scenario's ``[fmus]`` swaps), neither built nor checked.

    ``host_only``: the FMUs are run on this machine and nowhere else (a run, a local
    sweep): from the cache, the native flavor's full set if it is current, else a set
    with this machine's binary alone, built in its own folder (``cache_dir(...,
    host_only=True)``). Whatever hands FMUs on (exports) keeps the default, False:
    every platform's binary. A folder given is built with every platform's binary (its
    FMUs may be handed on), or kept host-only if it holds a host-only set."""
    if fmu_dir is None:
        flavor = flavor or "python"
        fmi = fmi or 2
        with same_sources():  # each FMU's hash made once
            folder = cache_dir(flavor, fmi)
            if host_only and _has_host_only(flavor, fmi) and not _current(folder, flavor, fmi):
                folder = cache_dir(flavor, fmi, host_only=True)
            build_all(folder, only_stale=True, flavor=flavor, fmi=fmi, host_only=host_only)
        return folder
    folder = Path(fmu_dir)
    if flavor is not None or fmi is not None or overwrite:  # else kept as it is
        build_all(folder, only_stale=True, flavor=flavor, fmi=fmi, overwrite=overwrite, skip=skip)
    return folder


def _has_host_only(flavor: str, fmi: int) -> bool:
    """A run's cache may hold a set built for this machine alone: the native flavor's, and
    the Python flavor's FMI 2.0 set (its runtime built for this platform only: a first run
    then waits for zig's C library pieces of one platform, not two; issue 48)."""
    return flavor == "native" or (fmi == 2 and host_platform() in PYTHON_PLATFORMS)


def _current(folder: Path, flavor: str, fmi: int) -> bool:
    """True if ``folder`` holds the flavor's full set of FMI ``fmi``, current."""
    if flavor == "python":
        return all(is_current(folder / f"{c.name}.fmu", c) for c in COMPONENTS)
    from .native import is_current as native_current

    return all(native_current(folder / f"{c.name}.fmu", c, fmi) for c in NATIVE_COMPONENTS)
