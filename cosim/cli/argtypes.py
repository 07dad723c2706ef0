"""The command line's argument types: each refuses bad text in one line."""

from __future__ import annotations

import argparse
import re

from ..inputs.text import quote


def _number(text: str, zero: bool) -> float:
    """A finite number > 0 (``zero``: >= 0) from the command line."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{quote(text)} is not a number") from None
    if not (v >= 0 if zero else v > 0) or v == float("inf"):
        raise argparse.ArgumentTypeError(
            f"{quote(text)} is invalid: expected a finite number {'>=' if zero else '>'} 0"
        )
    return v


def _positive(text: str) -> float:
    return _number(text, zero=False)


def _non_negative(text: str) -> float:
    return _number(text, zero=True)


def _count(text: str) -> int:
    if not re.fullmatch(r"\+?\d{1,18}", text.strip()) or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{quote(text)} is invalid: expected an integer >= 1")
    return int(text)
