"""SSP archives on disk: unpacking (bounded, once per process), names, values.

Used by :mod:`glider_cosim.interop.ssp_import`; :class:`SSPError` is re-exported there.
"""

from __future__ import annotations

import atexit
import math
import re
import shutil
from pathlib import Path

from .archives import InputFileError, regular_file, safe_extract
from .tempdirs import new_temp_dir
from .text import quote, shown_path
from .values import INT_MAX, INT_MIN

SSD_NAME = "SystemStructure.ssd"


class SSPError(ValueError):
    """A malformed or unsupported SSP, or one that does not fit its FMUs.

    The message is one line: the SSP file, the element, what is wrong.
    """


_UNPACKED: dict[tuple[str, int, int], Path] = {}


@atexit.register
def _remove_unpacked() -> None:
    for folder in _UNPACKED.values():
        shutil.rmtree(folder, ignore_errors=True)


def locate(path: Path) -> tuple[Path, Path]:
    """(folder the sources are relative to, the .ssd file) of an archive, .ssd or folder.

    An archive is unpacked once per process and file version (the master keeps FMU
    binaries loaded, so the same archive must keep giving the same FMU paths); the
    folders are removed at exit.
    """
    shown = shown_path(path)
    if not path.exists():
        raise SSPError(f"{shown}: SSP file does not exist")
    if path.is_dir():
        return path, path / SSD_NAME
    try:
        regular_file(path, shown, "SSP file")
    except InputFileError as err:
        raise SSPError(str(err)) from None
    if path.suffix.lower() == ".ssd":
        return path.parent, path
    st = path.stat()
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _UNPACKED or not _UNPACKED[key].is_dir():
        folder = new_temp_dir("ssp_")
        try:
            safe_extract(path, folder, shown)
        except InputFileError as err:
            shutil.rmtree(folder, ignore_errors=True)
            raise SSPError(str(err).replace("zip archive", "SSP archive")) from None
        _UNPACKED[key] = folder
    return _UNPACKED[key], _UNPACKED[key] / SSD_NAME


def parse_value(text: str, tag: str, where: str) -> float | int | bool:
    """An ``ssv:Real``/``Integer``/``Boolean`` value attribute: a finite float, an exact
    32-bit integer, or ``true``/``false``/``1``/``0``; :class:`SSPError` otherwise."""
    try:
        if tag == "Real":
            value = float(text)
            if not math.isfinite(value):
                raise ValueError
            return value
        if tag == "Integer":
            value = int(text)
            if not INT_MIN <= value <= INT_MAX:
                raise ValueError
            return value
        if text in ("true", "1"):
            return True
        if text in ("false", "0"):
            return False
        raise ValueError
    except ValueError:
        raise SSPError(f"{where}: value {quote(text)} is not a valid {tag}") from None


def ssp_name(path: str | Path) -> str:
    """The run's name of an SSP (its file or folder name, made a plain name)."""
    p = Path(path)
    stem = p.parent.name if p.name == SSD_NAME else p.stem
    name = re.sub(r"[^A-Za-z0-9._+-]", "_", stem)[:100].lstrip(".-")
    return name or "ssp"
