"""Sphinx extension of the glider-cosim docs: the CLI reference generated from the parser.

``{glider-cli}`` walks :func:`glider_cosim.cli.build_parser` and writes one section per
subcommand (usage, description, every option with its default); at ``builder-inited`` the
checked-in FMU interface page is compared with the tables generated from freshly built
FMUs' model descriptions, and a stale page is a warning (an error under ``-W``); and the
README's picture (:data:`README_PICTURE`, the default run's glide angle) is drawn from a
run of the default scenario, rewritten only when its bytes change.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from docutils import nodes
from sphinx.application import Sphinx
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective

LOG = logging.getLogger(__name__)


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _help_of(parser: argparse.ArgumentParser, name: str) -> str:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                if choice.dest == name:
                    return choice.help or ""
    return ""


def option_id(command: str, action: argparse.Action) -> str:
    """The HTML id of one option of one subcommand (``cli-run-step``, ``cli-run-scenario``)."""
    name = action.option_strings[-1].lstrip("-") if action.option_strings else action.dest
    return nodes.make_id(f"cli-{command}-{name}")


def _default(action: argparse.Action) -> str | None:
    if action.default in (None, False, [], argparse.SUPPRESS) or action.nargs == 0:
        return None
    return str(action.default)


class CliDirective(SphinxDirective):
    """Every subcommand of ``glider-cosim`` and every one of its options."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        from glider_cosim.cli import build_parser
        from glider_cosim.cli.parser import _plain

        top = build_parser()
        out: list[nodes.Node] = []
        for name, sub in _subcommands(top).items():
            sec = nodes.section(ids=[nodes.make_id(f"cli-{name}")])
            sec += nodes.title(text=f"glider-cosim {name}")
            summary = _plain(sub.description or _help_of(top, name))
            if summary:
                sec += nodes.paragraph(text=summary)
            usage = sub.format_usage().removeprefix("usage: ").strip()
            block = nodes.literal_block(usage, usage)
            block["language"] = "text"
            sec += block
            table = nodes.definition_list(classes=["cli-options"])
            for action in sub._actions:
                if isinstance(action, argparse._HelpAction):
                    continue
                item = nodes.definition_list_item()
                term = nodes.term(ids=[option_id(name, action)])
                names = action.option_strings or [action.metavar or action.dest]
                for i, opt in enumerate(names):
                    if i:
                        term += nodes.Text(", ")
                    shown = (
                        opt
                        if not action.option_strings or action.nargs == 0
                        else (f"{opt} {action.metavar or action.dest.upper()}")
                    )
                    term += nodes.literal(shown, shown)
                item += term
                body = nodes.definition()
                text = _plain(action.help or "").replace("%(default)s", str(action.default))
                if text and text[-1] not in ".)":
                    text += "."
                para = nodes.paragraph(text=text)
                if action.choices and not isinstance(action.choices, dict):
                    para += nodes.Text(" Choices: ")
                    para += nodes.literal(text=", ".join(map(str, action.choices)))
                    para += nodes.Text(".")
                default = _default(action)
                if default is not None and "default" not in text:
                    para += nodes.Text(" Default: ")
                    para += nodes.literal(text=default)
                    para += nodes.Text(".")
                body += para
                item += body
                table += item
            sec += table
            out.append(sec)
        return out


def stale_interface_page(srcdir: Path) -> Path | None:
    """The FMU interface page under ``srcdir`` if it differs from the FMUs' model
    descriptions (the Python flavor, built into the per-user cache if missing), else None."""
    from glider_cosim.fmus.docs import interface_markdown
    from glider_cosim.fmus.folders import build_all, fmu_folder

    page = Path(srcdir) / "reference" / "fmu-interfaces.md"
    text = interface_markdown(build_all(fmu_folder(None), only_stale=True))
    return None if page.is_file() and page.read_text() == text else page


class CliSummaryDirective(SphinxDirective):
    """One line per subcommand: its name (a link to its section) and its help."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        from glider_cosim.cli import build_parser
        from glider_cosim.cli.parser import _plain

        top = build_parser()
        items = nodes.bullet_list()
        for name in _subcommands(top):
            para = nodes.paragraph()
            ref = nodes.reference("", "", refid=nodes.make_id(f"cli-{name}"))
            ref += nodes.literal(text=f"glider-cosim {name}")
            para += ref
            para += nodes.Text(f": {_plain(_help_of(top, name))}")
            items += nodes.list_item("", para)
        return [items]


def check_fmu_interfaces(app: Sphinx) -> None:
    """Warn when the FMU interface page differs from the FMUs' model descriptions."""
    page = stale_interface_page(Path(app.srcdir))
    if page is not None:
        LOG.warning(
            "%s is stale: it differs from the FMUs' model descriptions; "
            "run python -m glider_cosim.fmus.docs",
            page,
        )


#: the README's one picture, relative to the docs' source folder
README_PICTURE = Path("_static") / "default-glide-angle.png"


def draw_readme_picture() -> bytes:
    """The README's picture: the glide-angle PNG of ``glider-cosim run`` (the default
    scenario, Python flavor, in memory), as the run draws it (``figures.plots``)."""
    import tempfile

    from glider_cosim.figures.mpl import draw_png
    from glider_cosim.figures.plots import build_specs
    from glider_cosim.runner import simulate

    result = simulate("default", out=None, plots=False)
    with tempfile.TemporaryDirectory(prefix="glider_docs_") as tmp:
        ((spec, path, meta),) = build_specs(result, Path(tmp), names=("glide_angle",))
        return Path(draw_png(spec, path, metadata=meta)).read_bytes()


def write_readme_picture(app: Sphinx) -> None:
    """Draw the README's picture into the docs' ``_static`` folder (only if it changed)."""
    path = Path(app.srcdir) / README_PICTURE
    png = draw_readme_picture()
    if not (path.is_file() and path.read_bytes() == png):
        path.write_bytes(png)
        LOG.info("drew %s (the default run's glide angle)", path)


def setup(app: Sphinx) -> dict[str, object]:
    app.add_directive("glider-cli", CliDirective)
    app.add_directive("glider-cli-summary", CliSummaryDirective)
    app.connect("builder-inited", check_fmu_interfaces)
    app.connect("builder-inited", write_readme_picture)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
