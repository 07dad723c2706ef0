"""A package's public names imported on first use (PEP 562), so that importing one light
submodule (``glider_cosim.master.errors`` for the command line's parser) does not import
the whole package (fmpy, numpy).

Use in a package's ``__init__``::

    __getattr__, __dir__ = lazy_names(__name__, {"CoSimulation": "cosimulation", ...})
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any


def lazy_names(
    package: str, names: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package``: each of ``names`` (public name ->
    the submodule it lives in, or a module's full dotted name) is imported from there on
    first access and kept."""

    def getattr_(name: str) -> Any:
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        where = module if "." in module else f"{package}.{module}"
        value = getattr(importlib.import_module(where), name)
        setattr(sys.modules[package], name, value)
        return value

    def dir_() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names))

    return getattr_, dir_
