"""The native FMUs' platforms: FMI 2's and FMI 3's binary folders, macOS' universal
file, and the staged sources (compiling: :mod:`glider_cosim.fmus.objects`)."""

from __future__ import annotations

import shutil
import tempfile
import time
import zipfile
from pathlib import Path

from glider_fmi import macho, toolchain

from .files import cache_root, package_version

#: FMI 2's binary folders: its standard ``linux64``, ``win64`` and ``darwin64`` (one
#: universal file for both macOS architectures), and ``aarch64-linux`` (no standard
#: name; FMI 3's tuple, where tools that know FMI 3 look)
FMI2_DIRS = {
    "x86_64-linux": "binaries/linux64",
    "aarch64-linux": "binaries/aarch64-linux",
    "x86_64-windows": "binaries/win64",
    "x86_64-darwin": "binaries/darwin64",
    "aarch64-darwin": "binaries/darwin64",
}


def binary_entries(name: str, built: dict[str, Path], fmi: int) -> dict[str, bytes]:
    """The FMU's binaries (zip path -> bytes) from the libraries ``built`` per platform:
    FMI 3 one per platform tuple, FMI 2 in its folders with both macOS slices in one
    universal ``darwin64/<id>.dylib``."""
    entries: dict[str, bytes] = {}
    darwin = []
    for key, path in built.items():
        platform = toolchain.PLATFORMS[key]
        if fmi == 3:
            entries[f"{platform.fmi3_dir}/{name}{platform.suffix}"] = path.read_bytes()
        elif platform.os == "darwin":
            darwin.append(path.read_bytes())
        else:
            entries[f"{FMI2_DIRS[key]}/{name}{platform.suffix}"] = path.read_bytes()
    if darwin:
        entries[f"{FMI2_DIRS['x86_64-darwin']}/{name}.dylib"] = macho.fat_binary(darwin)
    return entries


def stage(key: str, files: dict[str, bytes], fallback: Path) -> Path:
    """``files`` (name -> bytes) in a ``sources/`` folder staged once per content in the
    FMU cache (``<cache>/<version>/native-src/<key>/sources``): zig's cache keys on the
    source paths, so files the FMUs share (the layer, the plant model) are compiled once
    per platform, and a rebuild reuses every object. The folder is written under a
    temporary name and renamed (complete or absent); under ``fallback`` when the cache
    cannot be written."""
    final = cache_root() / package_version() / "native-src" / key
    if (final / "sources").is_dir():
        return final / "sources"
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
        part = Path(tempfile.mkdtemp(prefix=f".{key}-", dir=final.parent))
    except OSError:
        part = final = fallback / "staged"
    src = part / "sources"
    src.mkdir(parents=True)
    for name, data in files.items():
        (src / name).write_bytes(data)
    if part != final:
        try:
            part.rename(final)
        except OSError:  # another process staged it meanwhile
            shutil.rmtree(part, ignore_errors=True)
    return final / "sources"


def zip_member(name: str) -> zipfile.ZipInfo:
    """A zip entry for a binary: compressed, mode rwxr-xr-x, dated now."""
    info = zipfile.ZipInfo(name, time.localtime()[:6])
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o100755 << 16
    return info
