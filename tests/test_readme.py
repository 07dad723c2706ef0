"""README.md: at most 150 lines, the test command CI runs, its links and tour commands valid."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

from glider_cosim.cli import build_parser

ROOT = Path(__file__).parents[1]
README = (ROOT / "README.md").read_text()


def _sh_blocks(text: str) -> list[str]:
    return re.findall(r"```sh\n(.*?)\n```", text, flags=re.S)


def test_the_readme_is_short():
    assert len(README.splitlines()) <= 150


def quick_start() -> list[str]:
    """The Quick start's commands, comments stripped: install and run, then the tests."""
    block = _sh_blocks(README[README.index("## Quick start") :])[0]
    return [ln.split("#")[0].strip() for ln in block.splitlines() if ln.split("#")[0].strip()]


def test_the_quick_start_is_two_commands():
    assert quick_start() == ["pip install -e '.[test]' && glider-cosim run", "python -m pytest -q"]


def test_ci_runs_the_quick_start_as_the_readme_spells_it():
    ci = [ln.strip() for ln in (ROOT / ".ci" / "run").read_text().splitlines()]
    assert [c for c in quick_start() if c not in ci] == []
    # in that order, and no other pytest command (CI's verdict is the README's command)
    assert ci.index(quick_start()[0]) < ci.index(quick_start()[1])
    assert [ln for ln in ci if re.match(r"python3? -m pytest", ln)] == [quick_start()[1]]


def test_the_install_command_installs_what_the_tests_import():
    """The extra the Quick start installs brings the docs tools too: the suite builds the
    site (tests/integration/test_docs.py needs sphinx, myst and docutils)."""
    import tomllib

    extra = re.search(r"\.\[(\w+)\]", quick_start()[0]).group(1)
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]

    def names(group: str) -> set[str]:
        out: set[str] = set()
        for req in extras[group]:
            name = re.match(r"[A-Za-z0-9_.-]+", req).group(0)
            inner = re.search(r"\[([\w,]+)\]", req)
            if name == project["name"] and inner:
                for g in inner.group(1).split(","):
                    out |= names(g)
            else:
                out.add(name.lower())
        return out

    assert {"sphinx", "myst-parser", "myst-nb", "pytest", "ruff"} <= names(extra)
    assert names("docs") <= names(extra)


def test_every_relative_link_of_the_readme_exists():
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README)
    local = [x for x in links if "://" not in x]
    assert len(local) >= 15
    assert [x for x in local if not (ROOT / x).is_file()] == []


def test_every_tour_command_parses():
    parser = build_parser()
    tour = README[README.index("## A tour") :]
    lines = _sh_blocks(tour)[0].splitlines()
    assert 8 <= len(lines) <= 12
    for line in lines:
        args = shlex.split(line.split("#")[0])
        assert args[0] == "glider-cosim", line
        parser.parse_args(args[1:])  # exits 2 on a wrong option
