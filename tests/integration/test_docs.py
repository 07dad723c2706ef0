"""The documentation site (docs/): it builds with warnings as errors, its tutorial runs,
its reference has every CLI option and every public API name, every internal link
resolves, and headless Chromium shows the index and the CLI reference without errors."""

from __future__ import annotations

import argparse
import importlib
import subprocess
import sys
import time
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest
from docs_browser import Browser, pixel_spread
from system_tools import require_tool

from glider_cosim.cli import build_parser

pytestmark = pytest.mark.integration
ROOT = Path(__file__).parents[2]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS / "_ext"))
import glider_docs  # noqa: E402

#: the subpackages whose ``__all__`` is the public API
PUBLIC = ("glider_cosim.cli", "glider_cosim.inputs", "glider_cosim.master",
          "glider_cosim.runner", "glider_cosim.verify")  # fmt: skip


def _files(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*") if "__pycache__" not in p.parts}


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site as CI builds it, into a temporary folder (nothing written to docs/)."""
    out = tmp_path_factory.mktemp("docs") / "html"
    before = _files(DOCS)
    t0 = time.monotonic()
    p = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         "-d", str(out.parent / "doctrees"), str(DOCS), str(out)],
        capture_output=True, text=True, timeout=600, cwd=ROOT,
    )  # fmt: skip
    assert p.returncode == 0, (p.stdout + p.stderr)[-4000:]
    # Sphinx's own messages (the kernel's "[IPKernelApp] WARNING | ... TCP" note is not one)
    assert "WARNING:" not in p.stderr and "ERROR:" not in p.stderr, p.stderr[-4000:]
    assert _files(DOCS) == before, sorted(map(str, _files(DOCS) ^ before))
    print(f"sphinx build: {time.monotonic() - t0:.1f} s")
    return out


class _Page(HTMLParser):
    """The ids, links (href, src) and text of one HTML page."""

    def __init__(self) -> None:
        super().__init__()
        self.ids: set[str] = set()
        self.links: list[str] = []
        self.text: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        for k, v in attrs:
            if k in ("id", "name") and v:
                self.ids.add(v)
            if (k == "href" and tag in ("a", "link")) or (k == "src" and tag in ("img", "script")):
                if v:
                    self.links.append(v)

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def broken_links(site: Path) -> list[str]:
    """Every internal href/src of every page whose file or #fragment does not exist."""
    pages = {p: parse(p) for p in site.rglob("*.html")}
    bad = []
    for path, page in pages.items():
        for link in page.links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc:  # external: not ours to check here
                continue
            target = (path.parent / unquote(parts.path)).resolve() if parts.path else path
            if target.is_dir():
                target = target / "index.html"
            rel = path.relative_to(site)
            if not target.is_file():
                bad.append(f"{rel}: {link} (no file)")
            elif parts.fragment and target.suffix == ".html":
                ids = pages[target].ids if target in pages else parse(target).ids
                if unquote(parts.fragment) not in ids:
                    bad.append(f"{rel}: {link} (no id {parts.fragment!r})")
    return bad


def test_every_internal_link_resolves(site):
    assert len(list(site.rglob("*.html"))) >= 25
    assert broken_links(site) == []


def test_the_link_check_finds_a_broken_link(site, tmp_path):
    (tmp_path / "a.html").write_text('<a href="b.html#nope">x</a><a href="c.html">y</a>'
                                     '<img src="d.png"><a id="me" href="#me">z</a>')  # fmt: skip
    (tmp_path / "b.html").write_text('<p id="yes">b</p>')
    assert broken_links(tmp_path) == [
        "a.html: b.html#nope (no id 'nope')",
        "a.html: c.html (no file)",
        "a.html: d.png (no file)",
    ]


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


def test_every_cli_option_is_in_the_reference(site):
    page = parse(site / "reference" / "cli.html")
    text = " ".join(page.text)
    missing = []
    subs = _subcommands(build_parser())
    assert len(subs) >= 10
    for name, sub in subs.items():
        if f"cli-{name}" not in page.ids:
            missing.append(name)
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            if glider_docs.option_id(name, action) not in page.ids:
                missing.append(f"{name} {action.option_strings or action.dest}")
            for opt in action.option_strings:
                if opt not in text:
                    missing.append(f"{name} {opt} (text)")
    assert missing == []


def test_every_public_api_name_is_in_the_reference(site):
    ids = parse(site / "reference" / "python-api.html").ids
    modules = {m: importlib.import_module(m) for m in PUBLIC}
    missing = []
    for m, mod in modules.items():
        for name in mod.__all__:
            # a name re-exported by two subpackages is documented once, under either
            homes = [
                o for o, omod in modules.items() if getattr(omod, name, None) is getattr(mod, name)
            ]
            if not any(f"{o}.{name}" in ids for o in homes):
                missing.append(f"{m}.{name}")
    assert sum(len(m.__all__) for m in modules.values()) >= 30
    assert missing == []


def test_the_tutorial_ran_at_build_time(site):
    page = parse(site / "getting-started" / "first-run.html")
    text = " ".join(page.text)
    assert "ok - settled" in text
    assert "settling time" in text and "columns, e.g. time" in text
    images = [src for src in page.links if src.endswith(".png")]
    assert images, "the tutorial's plot is missing"
    png = (site / "getting-started" / images[0]).read_bytes()
    assert png.startswith(b"\x89PNG") and pixel_spread(png) > 0.02


def test_the_fmu_interface_page_is_the_model_descriptions(tmp_path):
    assert glider_docs.stale_interface_page(DOCS) is None
    (tmp_path / "reference").mkdir()
    page = tmp_path / "reference" / "fmu-interfaces.md"
    page.write_text(
        (DOCS / "reference" / "fmu-interfaces.md").read_text().replace("| N |", "| kN |", 1)
    )
    assert glider_docs.stale_interface_page(tmp_path) == page


@pytest.fixture(scope="module")
def browser():
    require_tool("chromium", "chromium-browser")
    with Browser() as b:
        yield b


@pytest.mark.parametrize("page", ["index.html", "reference/cli.html"])
def test_chromium_shows_the_page_without_errors(site, browser, page, tmp_path):
    visit = browser.visit((site / page).as_uri())
    shot = tmp_path / (page.replace("/", "-") + ".png")
    assert visit.errors == []
    assert pixel_spread(visit.png, shot) > 0.05, f"{page} looks blank: {shot}"


def test_the_chromium_check_sees_errors_and_blank_pages(browser, tmp_path):
    bad = tmp_path / "bad.html"
    bad.write_text('<html><body><img src="missing.png"><script>console.error("boom");'
                   "undefined_function();</script></body></html>")  # fmt: skip
    visit = browser.visit(bad.as_uri())
    assert any("boom" in e for e in visit.errors), visit.errors
    assert any("undefined_function" in e for e in visit.errors), visit.errors
    assert any("missing.png" in e or "ERR_FILE_NOT_FOUND" in e for e in visit.errors), visit.errors
    assert pixel_spread(visit.png) < 0.01


def test_chromium_finds_no_console_error_on_any_page(site, browser):
    pages = sorted(site.rglob("*.html"))
    assert len(pages) >= 25
    errors = {}
    for page in pages:
        visit = browser.visit(page.as_uri(), settle=0.05)
        if visit.errors:
            errors[str(page.relative_to(site))] = visit.errors
    assert errors == {}
