"""The C helpers a run loads from the FMU cache, built there once by the FMUs' toolchain:
the master's fast loop (:mod:`glider_cosim.master.fastloop`) and the native monolithic
loop (:mod:`glider_cosim.runner.monolithic`).

Each module passes its own C files; compiling them into the cache is the build's
concern, here beside the FMUs' other builds: ``<cache>/<version>/<stem>-<hash>/``
(:func:`glider_cosim.fmus.files.cache_root`, listed by ``glider-cosim cache``), with the
toolchain of :mod:`glider_fmi.toolchain` (zig's C compiler by default).
"""

from __future__ import annotations

import hashlib
import os
import sys
from collections.abc import Sequence
from pathlib import Path


def build_helper(
    stem: str,
    sources: Sequence[Path],
    headers: Sequence[Path],
    flags: Sequence[str],
    what: str,
    lto: bool = False,
) -> Path:
    """A shared library of ``sources`` for this process, built once per FMU cache.

    Parameters
    ----------
    stem : str
        The library's name: ``<cache>/<version>/<stem>-<hash>/<stem><suffix>``, the hash
        over the sources, the headers they include, the flags and the compiler.
    sources, headers : sequence of Path
        The C files compiled, the files they include.
    flags : sequence of str
        Compile flags after the toolchain's shared-library ones.
    what : str
        What it is, for the compiler's error message.
    lto : bool
        Built with link-time optimisation where the native FMUs are
        (:func:`glider_fmi.toolchain.host_command`).

    Returns
    -------
    Path
        The library. Built under a temporary name and renamed, so concurrent processes
        never load a half-written file; in this process's temporary folder when the
        cache cannot be written.

    Raises
    ------
    OSError
        No compiler for this machine, or it failed.
    """
    from glider_fmi import toolchain

    from ..inputs.tempdirs import new_temp_dir
    from .files import cache_root, package_version

    cmd = [*toolchain.host_command(lto=lto), *flags]
    h = hashlib.sha256()
    for path in (*sources, *headers):
        h.update(path.read_bytes())
    h.update(" ".join([*flags, toolchain.fingerprint(), f"lto={lto}"]).encode())
    suffix = {"win32": ".dll", "darwin": ".dylib"}.get(sys.platform, ".so")
    folder = cache_root() / package_version() / f"{stem}-{h.hexdigest()[:16]}"
    out = folder / f"{stem}{suffix}"
    if out.is_file():
        return out
    try:
        folder.mkdir(parents=True, exist_ok=True)
        part = folder / f".{stem}-{os.getpid()}{suffix}"
    except OSError:
        out = new_temp_dir(f"{stem}_") / f"{stem}{suffix}"
        part = out
    try:
        toolchain.run([*cmd, *map(str, sources), "-o", str(part)], what)
        if part != out:
            os.replace(part, out)
    finally:
        if part != out:
            part.unlink(missing_ok=True)
            for extra in folder.glob(f".{stem}-{os.getpid()}.*"):  # zig's .pdb/.lib
                extra.unlink(missing_ok=True)
    return out
