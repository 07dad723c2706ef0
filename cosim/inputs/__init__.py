"""Checks of everything that comes in from outside: files, archives, values, limits.

:mod:`.text` bounds what a message quotes, :mod:`.archives` reads FMU and SSP files
(regular files only, complete FMUs, bounded extraction), :mod:`.values` checks values
against a variable's type and unit, :mod:`.check` checks a scenario against the model
descriptions and our parameter tables before any FMU is instantiated.
"""

from .text import quote

__all__ = ["quote"]
