"""CHANGELOG.md keeps the Keep a Changelog form, and its newest release is the version."""

from __future__ import annotations

import re
from pathlib import Path

import glider_cosim

CHANGELOG = Path(__file__).resolve().parent.parent / "CHANGELOG.md"
RELEASE = re.compile(r"^## \[(\d+\.\d+\.\d+)\] - (\d{4}-\d{2}-\d{2})$")
GROUPS = {"Added", "Changed", "Deprecated", "Removed", "Fixed", "Security"}


def sections(text: str) -> list[str]:
    """The ``## `` headings of a changelog, in order."""
    return [line for line in text.splitlines() if line.startswith("## ")]


def check(text: str, version: str) -> list[str]:
    """What breaks the form in ``text``; empty when it holds."""
    problems = []
    heads = sections(text)
    if not heads or heads[0] != "## [Unreleased]":
        problems.append("the first section is not '## [Unreleased]'")
    releases = []
    for head in heads[1:]:
        m = RELEASE.match(head)
        if m is None:
            problems.append(f"not '## [X.Y.Z] - YYYY-MM-DD': {head!r}")
        else:
            releases.append((tuple(int(p) for p in m[1].split(".")), m[2]))
    if not releases:
        problems.append("no release section")
    elif ".".join(map(str, releases[0][0])) != version:
        problems.append(f"the newest release is not the version {version}")
    if releases != sorted(releases, reverse=True):
        problems.append("releases are not newest first, with their dates")
    for line in text.splitlines():
        if line.startswith("### ") and line[4:] not in GROUPS:
            problems.append(f"not a Keep a Changelog group: {line!r}")
    return problems


def test_changelog_form_and_version():
    assert check(CHANGELOG.read_text(encoding="utf-8"), glider_cosim.__version__) == []


def test_the_check_can_fail():
    good = "# Changelog\n\n## [Unreleased]\n\n## [0.5.0] - 2026-12-06\n### Added\n- x\n"
    assert check(good, "0.5.0") == []
    assert check(good, "0.1.0") != []
    assert check(good.replace("[0.5.0] - 2026-12-06", "0.5.0 (unreleased)"), "0.5.0") != []
    assert check(good.replace("### Added", "### Issue 53"), "0.5.0") != []
    older_first = good + "\n## [0.6.0] - 2026-12-07\n"
    assert check(older_first, "0.5.0") != []
