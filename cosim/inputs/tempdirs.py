"""One temporary folder per process tree for everything glider-cosim unpacks.

FMUs and SSP archives are extracted under :func:`temp_root`. The first process that
asks for it creates ``$TMPDIR/glider_cosim_XXXX`` and exports its path in
``GLIDER_COSIM_TMP``; processes it starts (CLI subprocesses, Dask workers) make their
own sub-folder inside it. Each process removes its own folder at exit (``atexit``, and
:func:`cleanup` before the CLI's early exit); the owner removes the whole tree, so a
child that was killed leaves nothing behind either.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

ENV = "GLIDER_COSIM_TMP"
_state: dict[str, Path | bool] = {}


def temp_root() -> Path:
    """This process's temporary folder (created on first use).

    Returns
    -------
    Path
        An existing folder that :func:`cleanup` removes.
    """
    root = _state.get("root")
    if isinstance(root, Path) and root.is_dir():
        return root
    parent = os.environ.get(ENV)
    if parent and Path(parent).is_dir() and not _state.get("owner"):
        root = Path(tempfile.mkdtemp(prefix=f"p{os.getpid()}_", dir=parent))
        _state.update(root=root, owner=False)
    else:
        root = Path(tempfile.mkdtemp(prefix="glider_cosim_"))
        _state.update(root=root, owner=True)
        os.environ[ENV] = str(root)
    return root


def new_temp_dir(prefix: str) -> Path:
    """A fresh folder inside :func:`temp_root` (removed with it)."""
    return Path(tempfile.mkdtemp(prefix=prefix, dir=temp_root()))


def cleanup() -> None:
    """Remove this process's temporary folder (idempotent; safe with loaded binaries)."""
    root = _state.pop("root", None)
    owner = _state.pop("owner", False)
    if isinstance(root, Path):
        shutil.rmtree(root, ignore_errors=True)
        if owner and os.environ.get(ENV) == str(root):
            del os.environ[ENV]


atexit.register(cleanup)
