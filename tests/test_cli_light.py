"""The command line's front: --version, a bare ``glider-cosim``, each command's parser and
help (issue 53 removed the import budgets that stood here)."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _entry_point() -> tuple[str, str]:
    """``(module, function)`` of the installed ``glider-cosim`` console script."""
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    module, _, func = scripts["glider-cosim"].partition(":")
    return module, func


def _cli(*argv: str) -> subprocess.CompletedProcess:
    module, func = _entry_point()
    code = f"import sys; from {module} import {func}; sys.argv[0] = 'glider-cosim'; {func}()"
    return subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True,
                          timeout=60, check=False)  # fmt: skip


def test_version_prints_the_installed_version():
    from importlib.metadata import version

    proc = _cli("--version")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == f"glider-cosim {version('glider-cosim')}\n"


def test_a_bare_command_lists_every_command_and_the_first_to_try():
    from glider_cosim.cli import build_parser

    proc = _cli()
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    sub = next(a for a in build_parser()._actions if hasattr(a, "_choices_actions"))
    listed = re.findall(r"^  (\S+)  ", proc.stdout, re.M)
    assert listed == [c.dest for c in sub._choices_actions]
    assert len(listed) >= 10
    assert "First try: glider-cosim run" in proc.stdout


def test_export_fmu_help_and_its_page_say_the_one_fmu_runs_jacobi_coupling(capsys):
    """Issue 45 item 4: the one-FMU export's Jacobi coupling, which explains its 0.47 deg
    from `run`, is said in `export-fmu --help` and in docs/how-to/export.md (the figure is
    measured by tests/integration/test_onefmu.py)."""
    from glider_cosim.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["export-fmu", "--help"])
    assert exit_.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "Inside, the FMUs run with Jacobi coupling" in text
    assert "equal `glider-cosim run --coupling jacobi` bit for bit" in text
    assert "differ from the default run by up to 0.47 deg in glide angle" in text
    page = " ".join((ROOT / "docs" / "how-to" / "export.md").read_text().split())
    assert "**The one FMU runs Jacobi coupling**" in page and "0.47 deg" in page


def _options(parser) -> dict[str, dict[str, list]]:
    """Each command's options: its parser's actions as (flags, dest, default, choices,
    help)."""
    sub = next(a for a in parser._actions if hasattr(a, "_choices_actions"))
    return {
        name: [(a.option_strings, a.dest, a.default, a.choices, a.help) for a in p._actions]
        for name, p in sub.choices.items()
    }


def test_a_command_parser_builds_that_command_alone_and_parses_it_the_same():
    """`main` builds the options of the command it runs alone; the others are named with
    their help. That command's options, its parse of
    the same arguments and the list of commands are those of the whole parser."""
    from glider_cosim.cli import build_parser

    whole = build_parser()
    argv = ["run", "paper", "--no-plots", "--flavor", "native", "--set", "controller.K_c=6",
            "--step", "0.01", "-q"]  # fmt: skip
    for command in ("run", "sweep", "verify", "report"):
        only = build_parser(command)
        assert _options(only)[command] == _options(whole)[command]
        others = {n: o for n, o in _options(only).items() if n != command}
        assert all(len(o) == 1 for o in others.values()), others  # -h alone
        assert list(_options(only)) == list(_options(whole))
    assert vars(build_parser("run").parse_args(argv)) == vars(whole.parse_args(argv))


def test_the_version_is_one_value_read_without_importlib_metadata():
    """The cache folders and --version read glider_cosim.__version__, which the installed
    metadata is made from (pyproject.toml's dynamic version): one place."""
    from importlib.metadata import version

    import glider_cosim
    from glider_cosim.fmus.files import package_version

    assert glider_cosim.__version__ == version("glider-cosim") == package_version()
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" in pyproject["project"]["dynamic"]
    assert pyproject["tool"]["setuptools"]["dynamic"]["version"] == {
        "attr": "glider_cosim.__version__"
    }
