"""A missing system tool skips its test, with the reason, or fails it under CI
(``GLIDER_COSIM_REQUIRE_TOOLS=1``): the helper and the ``requires_tool`` marker."""

from __future__ import annotations

import sys

import pytest
from system_tools import REQUIRE_TOOLS_ENV, require_tool, tool_missing

HERE = __import__("pathlib").Path(__file__).parent
ABSENT = "glider-no-such-tool"


def test_a_present_tool_is_found_by_its_path():
    assert require_tool(ABSENT, "python3" if sys.platform != "win32" else "python")


@pytest.mark.parametrize("value", ["", "0"])
def test_an_absent_tool_skips_with_its_reason(monkeypatch, value):
    monkeypatch.setenv(REQUIRE_TOOLS_ENV, value)
    with pytest.raises(pytest.skip.Exception) as e:
        require_tool(ABSENT, install="build it")
    assert str(e.value) == f"{ABSENT} is not installed (build it; .ci/run installs it)"


def test_an_absent_tool_fails_when_ci_requires_every_tool(monkeypatch):
    monkeypatch.setenv(REQUIRE_TOOLS_ENV, "1")
    with pytest.raises(pytest.fail.Exception) as e:
        require_tool(ABSENT)
    assert str(e.value) == (
        f"{ABSENT} is not installed (apt-get install {ABSENT}; .ci/run installs it) "
        f"({REQUIRE_TOOLS_ENV} is set: every system tool is required)"
    )
    with pytest.raises(pytest.fail.Exception, match=r"^a sysroot is missing \("):
        tool_missing("a sysroot is missing")


MARKED = f"""
import pytest

@pytest.mark.requires_tool("{ABSENT}", "{ABSENT}-2")
def test_marked():
    pass

@pytest.mark.requires_tool("{ABSENT}", "python3")
def test_marked_present():
    pass
"""

CONFTEST = f"""
import importlib.util, sys
sys.path.insert(0, {str(HERE)!r})
spec = importlib.util.spec_from_file_location("glider_conftest", {str(HERE / "conftest.py")!r})
ours = importlib.util.module_from_spec(spec)
spec.loader.exec_module(ours)
pytest_runtest_setup = ours.pytest_runtest_setup

def pytest_configure(config):
    config.addinivalue_line("markers", "requires_tool: see tests/system_tools.py")
"""


@pytest.mark.parametrize("required", [False, True])
def test_the_marker_skips_or_fails(pytester, monkeypatch, required):
    monkeypatch.setenv(REQUIRE_TOOLS_ENV, "1" if required else "")
    pytester.makeconftest(CONFTEST)
    pytester.makepyfile(MARKED)
    r = pytester.runpytest("-rs", "-p", "no:cacheprovider")
    if required:
        r.assert_outcomes(passed=1, errors=1)  # failed in its set-up
        r.stdout.fnmatch_lines([f"*{ABSENT} or {ABSENT}-2 is not installed*is set: every*"])
    else:
        r.assert_outcomes(passed=1, skipped=1)
        r.stdout.fnmatch_lines([f"SKIPPED*{ABSENT} or {ABSENT}-2 is not installed*"])
