"""What ``setup.py`` gives setuptools (the packages, their folders and data, from the
component registry), read by running it with ``setuptools.setup`` caught."""

from __future__ import annotations

import runpy
from pathlib import Path
from typing import Any
from unittest import mock

ROOT = Path(__file__).resolve().parents[1]


def setup_kwargs() -> dict[str, Any]:
    """The keyword arguments ``setup.py`` passes to ``setuptools.setup``."""
    import setuptools

    given: dict[str, Any] = {}
    with mock.patch.object(setuptools, "setup", lambda **kw: given.update(kw)):
        runpy.run_path(str(ROOT / "setup.py"))
    return given
