"""System tools the tests need beyond Python (compilers, emulators, browsers).

The README promises that ``python -m pytest -q`` passes with Python >= 3.11 and nothing
else: a test that needs a system tool which is absent is *skipped*, with its reason. CI
(``.ci/run``) installs every tool and sets ``GLIDER_COSIM_REQUIRE_TOOLS=1``, which turns
such a skip into a failure, so that nothing is skipped there unseen.

Use :func:`require_tool` inside a test or fixture, :func:`tool_missing` where the check
is not a program on ``PATH`` (a sysroot, a header), or the marker
``@pytest.mark.requires_tool("chromium", "chromium-browser")`` (any one of the names
will do) on a test or a module (see ``conftest.py``).
"""

from __future__ import annotations

import os
import shutil
from typing import NoReturn

import pytest

#: set to 1 by CI: a missing system tool fails the test instead of skipping it
REQUIRE_TOOLS_ENV = "GLIDER_COSIM_REQUIRE_TOOLS"


def tools_required() -> bool:
    """Whether a missing tool is a failure (``GLIDER_COSIM_REQUIRE_TOOLS=1``, set by CI)."""
    return os.environ.get(REQUIRE_TOOLS_ENV, "") not in ("", "0")


def tool_missing(reason: str) -> NoReturn:
    """Skip the current test with ``reason``, or fail it when CI requires every tool."""
    __tracebackhide__ = True  # the skip is reported at the test's line, not here
    if tools_required():
        pytest.fail(f"{reason} ({REQUIRE_TOOLS_ENV} is set: every system tool is required)")
    pytest.skip(reason)


def require_tool(*names: str, install: str | None = None) -> str:
    """The path of the first of ``names`` found on ``PATH``; else the test is skipped (or
    failed under CI, see :func:`tool_missing`) with a reason naming the tool.

    Parameters
    ----------
    names
        program names, any one of which will do (e.g. ``"chromium", "chromium-browser"``)
    install
        how to get it, named in the reason (default: the Debian package of the same name)
    """
    __tracebackhide__ = True
    for name in names:
        if found := shutil.which(name):
            return found
    how = install or f"apt-get install {names[0]}"
    tool_missing(f"{' or '.join(names)} is not installed ({how}; .ci/run installs it)")
