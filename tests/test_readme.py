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


def test_the_readme_runs_the_test_command_of_ci():
    ci = (ROOT / ".ci" / "run").read_text()
    (command,) = [ln.strip() for ln in ci.splitlines() if re.match(r"\s*python3? -m pytest", ln)]
    first = _sh_blocks(README)[0].splitlines()
    assert any(ln.split("#")[0].strip() == command.replace("python3", "python") for ln in first)
    assert first[0].split("#")[0].strip() == "pip install -e '.[test]' && glider-cosim run"


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
