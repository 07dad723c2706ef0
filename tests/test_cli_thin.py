"""The command line stays thin (issue 55, item 5): each command's function is a few lines
over one library call, and ``run``'s options are that call's keyword arguments."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

from glider_cosim.cli import build_parser, commands
from glider_cosim.runner.checked import run_checked

COMMANDS = Path(commands.__file__)
#: the most lines a command's function may have (its ``def`` line and body)
MOST_LINES = 25
#: options that ``main`` handles for every command (not passed to the library)
EVERY_COMMAND = {"help", "quiet"}


def long_functions(source: str, most: int) -> list[str]:
    """The ``_command`` functions of ``source`` longer than ``most`` lines."""
    tree = ast.parse(source)
    return [
        f"{f.name}: {f.end_lineno - f.lineno + 1} lines"
        for f in tree.body
        if isinstance(f, ast.FunctionDef) and f.name.startswith("_")
        and f.end_lineno - f.lineno + 1 > most
    ]  # fmt: skip


def missing_kwargs(dests: set[str], call) -> set[str]:
    """The options' dests that are no keyword parameter of ``call``."""
    return dests - EVERY_COMMAND - set(inspect.signature(call).parameters)


def test_each_command_is_a_few_lines():
    assert long_functions(COMMANDS.read_text(), MOST_LINES) == []
    assert set(commands.COMMANDS) == set(build_parser()._subparsers._group_actions[0].choices)  # noqa: SLF001


def test_run_options_are_keyword_arguments_of_the_library_call():
    sub = build_parser("run")._subparsers._group_actions[0]  # noqa: SLF001
    dests = {a.dest for a in sub.choices["run"]._actions}
    assert missing_kwargs(dests, run_checked) == set()


def test_the_checks_can_fail():
    long = "def _x():\n" + "    pass\n" * MOST_LINES
    assert long_functions(long, MOST_LINES) == [f"_x: {MOST_LINES + 1} lines"]

    def call(stop_time=None):
        return stop_time

    assert missing_kwargs({"stop_time", "out", "quiet"}, call) == {"out"}
