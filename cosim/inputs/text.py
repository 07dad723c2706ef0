"""Bounded quoting of user text in messages, and the "did you mean" of a misspelt name."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

QUOTE_LIMIT = 200


def quote(value: Any, limit: int = QUOTE_LIMIT) -> str:
    """``repr(value)``, cut to about ``limit`` characters (the length is then appended).

    Parameters
    ----------
    value : any
        The bad value or text (strings are quoted as Python literals).
    limit : int
        Characters of the value kept.

    Returns
    -------
    str
        One line.
    """
    if isinstance(value, str) and len(value) > limit:
        return f"{value[:limit]!r}... ({len(value)} characters)"
    if isinstance(value, bool):
        return "true" if value else "false"
    try:
        text = repr(value)
    except RecursionError:
        return f"<a deeply nested {type(value).__name__}>"
    if len(text) > limit:
        return f"{text[:limit]}... ({len(text)} characters)"
    return text


def one_line(message: str, limit: int = 4 * QUOTE_LIMIT) -> str:
    """A message on one line, at most about ``limit`` characters."""
    text = " ".join(str(message).split())
    if len(text) > limit:
        text = text[:limit] + f"... ({len(text)} characters)"
    return text


def prefix(kind: str = "error", command: str | None = None) -> str:
    """``"glider-cosim COMMAND: KIND: "`` (``"glider-cosim: KIND: "`` without a command):
    the one form of every error, warning and note line the console prints, argparse's
    too. ``kind`` is ``error``, ``warning`` or ``note``. A message never names its own
    command: the prefix does."""
    return f"glider-cosim {command}: {kind}: " if command else f"glider-cosim: {kind}: "


def shown_path(path: Any) -> str:
    """A file name for messages: as is, or quoted and cut if it is long or unprintable."""
    text = str(path)
    return text if len(text) <= QUOTE_LIMIT and text.isprintable() else quote(text)


def did_you_mean(word: Any, choices: Iterable[Any]) -> str:
    """``"; did you mean 'K_c'?"`` for the choice closest to a misspelt ``word`` (difflib,
    any case), or ``""`` if none is close; appended to a message that refuses ``word``."""
    if not isinstance(word, str) or len(word) > QUOTE_LIMIT:
        return ""
    names = {str(c).lower(): str(c) for c in choices}
    import difflib  # here: only a misspelt word needs it

    close = difflib.get_close_matches(word.lower(), list(names), n=1, cutoff=0.6)
    return f"; did you mean {names[close[0]]!r}?" if close else ""


def command_line(argv: Iterable[str], drop: Iterable[str] = ()) -> str:
    """``glider-cosim`` and its arguments ``argv`` as a shell would take them back
    (quoted where needed), without the flags in ``drop`` (e.g. ``--restart`` in a resume
    command): ``glider-cosim sweep --param 'plant.V_0=0.2 m/s'``."""
    import shlex

    dropped = set(drop)
    return shlex.join(["glider-cosim", *(w for w in argv if w not in dropped)])
