"""The documentation's sources (docs/): the four sections as glob toctrees, one title per
page, relative links to files that exist, and the shipped scenarios table as the code's."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from glider_cosim.scenarios.scenario import shipped_scenarios

DOCS = Path(__file__).parents[1] / "docs"
SECTIONS = ("getting-started", "how-to", "reference", "explanation")
PAGES = sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.parts)


def _prose(text: str) -> str:
    """The text outside fenced code blocks."""
    return re.sub(r"^(`{3,}|~{3,}).*?^\1\s*$", "", text, flags=re.S | re.M)


@pytest.mark.parametrize("section", SECTIONS)
def test_each_section_includes_its_pages_by_a_glob(section):
    index = (DOCS / section / "index.md").read_text()
    assert re.search(r"```\{toctree\}\n(:[^\n]*\n)*:glob:", index), section
    assert "\n*\n```" in index, f"{section}/index.md: its toctree ends with the glob '*'"
    assert f"{section}/index" in (DOCS / "index.md").read_text()


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(DOCS)))
def test_each_page_has_one_title_and_links_that_exist(page):
    prose = _prose(page.read_text())
    assert len(re.findall(r"^# ", prose, flags=re.M)) == 1, "one '# ' title per page"
    links = re.findall(r"\]\(([^)\s#]+)(?:#[^)]*)?\)", prose)
    local = [x for x in links if "://" not in x and not x.startswith("mailto:")]
    assert [x for x in local if not (page.parent / x).exists()] == []


def test_the_shipped_scenarios_table_is_the_shipped_scenarios():
    text = (DOCS / "reference" / "scenarios.md").read_text()
    table = text[text.index("| scenario | what |") : text.index("\n\n", text.index("| scenario"))]
    named = {
        n for row in table.splitlines()[2:] for n in re.findall(r"`([\w.+-]+)`", row.split("|")[1])
    }
    assert named == set(shipped_scenarios())


def test_use_the_fmus_opens_with_recipes_and_the_test_tables_are_on_the_reliability_page():
    """Issue 45 item 4: the page opens with the recipes (fmpy loop, fmusim, libcosim, Ecos,
    a C host), each a code block; the flavor and platform tables are on the reliability
    page."""
    page = (DOCS / "how-to" / "use-the-fmus.md").read_text()
    heads = re.findall(r"^## (.*)$", _prose(page), flags=re.M)
    assert heads[:5] == ["Your own loop in fmpy", "fmusim", "libcosim (OSP)", "Ecos", "A C host"]
    before_recipes = page[: page.index("## Your own loop in fmpy")]
    assert "|---|" not in before_recipes and "```" not in before_recipes
    assert "| flavor | build |" not in page and "| platform |" not in page
    reliability = (DOCS / "explanation" / "reliability.md").read_text()
    assert "\n## The FMUs: flavors, platforms and hosts tested\n" in reliability
    assert "| flavor | build |" in reliability and "| platform |" in reliability
