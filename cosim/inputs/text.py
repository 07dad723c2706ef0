"""Bounded quoting of user text in messages."""

from __future__ import annotations

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


def shown_path(path: Any) -> str:
    """A file name for messages: as is, or quoted and cut if it is long or unprintable."""
    text = str(path)
    return text if len(text) <= QUOTE_LIMIT and text.isprintable() else quote(text)
