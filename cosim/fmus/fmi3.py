"""FMI 3.0 builds of the three FMUs (``glider-cosim build --fmi 3``), both flavors.

The same models and the same FMI layer as the FMI 2.0 builds, with the layer's FMI 3.0
front end (``src/fmi/fmi3_layer.c``) instead of the FMI 2.0 one. The model description
is the FMI 2.0 build's, written in FMI 3.0 terms (:func:`fmi3_model_description`): the
same names, value references, causalities, variabilities, units, start values and
ranges, with FMI 3 types (``Float64``, ``Int32``, ``Boolean``), outputs and initial
unknowns by value reference. Event mode, clocks, early return and intermediate update
are not provided, and the capability flags say so.

Binaries: ``binaries/<platform tuple>/``: ``x86_64-linux`` and ``aarch64-linux`` (both
flavors), ``x86_64-windows``, ``x86_64-darwin`` and ``aarch64-darwin`` (native);
``sources/`` with ``buildDescription.xml`` (native)."""

from __future__ import annotations

import hashlib
import logging
import tempfile
import zipfile
from collections.abc import Collection
from pathlib import Path

from glider_fmi import compile as runtime

from . import lsref, native, osp
from .files import build_progress, replacing
from .fmi3_description import fmi3_model_description
from .python import COMPONENTS, build_component, shown_runtimes, source_hash

log = logging.getLogger(__name__)


#: resource holding the hash an FMI 3 FMU was built from
FMI3_HASH_FILE = "resources/glider_cosim_fmi3.sha256"


LINUX = "binaries/x86_64-linux"


WINDOWS = "binaries/x86_64-windows"


def fmi3_hash(name: str) -> str:
    """The Python flavor's FMI 3 build: its FMI 2 build's sources and the FMI 3 front end."""
    h = hashlib.sha256(f"fmi3 python {name}".encode())
    h.update(runtime.runtime_fingerprint(fmi3=True).encode())
    h.update(source_hash(next(c for c in COMPONENTS if c.name == name)).encode())
    return h.hexdigest()


def is_current(fmu: Path, name: str) -> bool:
    try:
        with zipfile.ZipFile(fmu) as z:
            return z.read(FMI3_HASH_FILE).decode().strip() == fmi3_hash(name)
    except (OSError, KeyError, zipfile.BadZipFile):
        return False


def _repackage(fmu2: Path, out: Path, binary: dict[str, Path]) -> Path:
    """The Python flavor's FMI 2 FMU as FMI 3: the model description rewritten, the FMI 2
    runtime replaced by the FMI 3 one, resources kept."""
    name = fmu2.stem
    fmu = out / f"{name}.fmu"
    out.mkdir(parents=True, exist_ok=True)
    with replacing(fmu) as part, zipfile.ZipFile(fmu2) as src, \
            zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:  # fmt: skip
        md = fmi3_model_description(src.read("modelDescription.xml"), True)
        for item in src.infolist():
            if item.filename.startswith(("binaries/", "extra/")):
                continue
            if item.filename == "modelDescription.xml":
                z.writestr(item.filename, md)
            else:
                z.writestr(item, src.read(item))
        z.writestr(osp.extra_path(md), osp.generate(md))
        for entry, data in lsref.entries(md).items():  # FMI 3.0's types in its SSV files
            z.writestr(entry, data)
        for platform, lib in binary.items():
            z.write(lib, f"binaries/{platform}/{name}.so")
        z.writestr(FMI3_HASH_FILE, fmi3_hash(name) + "\n")
    osp.write_beside(fmu)  # where OSP's tools look for it
    return fmu


def build_fmi3(
    out: Path | str,
    flavor: str = "python",
    only_stale: bool = False,
    host_only: bool | None = None,
    names: Collection[str] | None = None,
    force: Collection[str] = (),
) -> dict:
    """Build the three FMI 3.0 FMUs of a flavor (those of ``names`` if given; ``force``:
    rebuilt even if current) into ``out``; model identifier -> path (``host_only``: see
    :func:`glider_cosim.fmus.native.build_native`)."""
    out = Path(out)
    if flavor == "native":
        return native.build_native(out, only_stale, 3, None, host_only, names, force)
    result = {c.name: out / f"{c.name}.fmu" for c in COMPONENTS if names is None or c.name in names}
    chosen = [c for c in COMPONENTS if c.name in result]
    stale = [c for c in chosen if not (only_stale and is_current(result[c.name], c.name))]
    todo = [c for c in chosen if c.name in force or c in stale]
    if not todo:
        return result
    platforms = runtime.PYTHON_PLATFORMS
    with tempfile.TemporaryDirectory(prefix="glider_fmi3_") as tmp, \
            build_progress(todo, "python", 3, out, platforms) as progress:  # fmt: skip
        stage = Path(tmp)
        progress.set_total(2 + len(todo))
        so3 = shown_runtimes(stage, progress, fmi3=True)
        so2 = shown_runtimes(stage, progress)
        for c in todo:
            progress.step(f"building {c.name}.fmu python")
            result[c.name] = _repackage(build_component(c, stage / "fmi2", so2), out, so3)
    return result
