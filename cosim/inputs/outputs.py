"""The output folders and files a user names: each refused in one line that names the
option it came from (``--out``, ``OUT``, ``--export``), before anything is written."""

from __future__ import annotations

import os
from pathlib import Path

from .text import one_line, quote


class UsageError(ValueError):
    """An argument cannot be used (the message names the option it came from)."""


def check_out_dir(path: Path, option: str) -> None:
    """Refuse an output folder that cannot be created or written.

    Parameters
    ----------
    path : Path
        The folder (it may not exist yet: its nearest existing parent is checked).
    option : str
        The option that named it, e.g. ``"--out"``, for the message.

    Raises
    ------
    UsageError
        The path is a file, or its nearest existing parent is not a writable folder.
    """
    shown = f"{option} {quote(str(path))}"
    if path.exists() and not path.is_dir():
        raise UsageError(f"{shown}: exists and is not a folder: expected a folder")
    parent = path
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise UsageError(f"{shown}: {quote(str(parent))} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UsageError(f"{shown}: {quote(str(parent))} is not writable")


def check_out_file(path: Path, option: str, suffix: str) -> None:
    """Refuse an output file that is a folder, does not end in ``suffix`` (e.g.
    ``".fmu"``), is in a folder that does not exist, or cannot be created.

    Raises
    ------
    UsageError
        The message names ``option`` and the path.
    """
    shown = f"{option} {quote(str(path))}"
    if path.is_dir():
        raise UsageError(f"{shown}: is a folder: expected a file name")
    if path.suffix.lower() != suffix:
        raise UsageError(f"{shown}: expected a file name ending in {suffix}")
    if not path.parent.is_dir() and not path.parent.exists():
        raise UsageError(f"{shown}: folder {quote(str(path.parent))} does not exist: expected "
                         "an existing folder (create it first)")  # fmt: skip
    check_out_dir(path.parent, option)


def os_error(err: OSError, paths: dict[str, Path]) -> UsageError:
    """An OSError as a one-line error naming the option whose path it concerns.

    Parameters
    ----------
    err : OSError
        What the file system said.
    paths : dict
        Option -> the path it named (the first one is named when none matches).
    """
    reason = err.strerror or one_line(err)
    filename = str(err.filename or "")
    for option, path in paths.items():
        if filename and (filename == str(path) or filename.startswith(f"{path}{os.sep}")):
            return UsageError(f"{option} {quote(str(path))}: {reason} ({quote(filename)})")
    option, path = next(iter(paths.items()))
    where = f" ({quote(filename)})" if filename else ""
    return UsageError(f"{option} {quote(str(path))}: {reason}{where}")
