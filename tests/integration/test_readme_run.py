"""The README as a newcomer reads it (issue 45): its picture is the one the docs build draws
from the default run, its "own controller" scenario runs as written, and every line of its
tour exits 0, each run as a subprocess of the installed ``glider-cosim`` in an empty folder."""

from __future__ import annotations

import importlib.util
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration
ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()
SRC = Path(__file__).parent / "fmus_src"


def _docs_extension():
    spec = importlib.util.spec_from_file_location(
        "glider_docs_ext", ROOT / "docs" / "_ext" / "glider_docs.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _committed(path: Path) -> bytes:
    """The file as committed (HEAD), or as on disk outside a git checkout (the docs build
    may have redrawn the working copy; the commit is what a reader of the README sees)."""
    rel = path.relative_to(ROOT).as_posix()
    if shutil.which("git") is None:  # no git, no checkout to read: the file as on disk
        return path.read_bytes()
    proc = subprocess.run(["git", "-C", str(ROOT), "show", f"HEAD:{rel}"], capture_output=True,
                          check=False)  # fmt: skip
    return proc.stdout if proc.returncode == 0 else path.read_bytes()


def test_the_readme_shows_the_picture_the_docs_build_draws():
    ext = _docs_extension()
    path = ROOT / "docs" / ext.README_PICTURE
    assert f"]({path.relative_to(ROOT).as_posix()})" in README
    fresh = ext.draw_readme_picture()
    assert fresh[:8] == b"\x89PNG\r\n\x1a\n"
    assert _committed(path) == fresh, (
        f"{path} is not what the docs build draws from the default run: build the docs "
        "(python -m sphinx -b html docs docs/_build/html) and commit the picture"
    )


def _cli(args: list[str], cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    exe = shutil.which("glider-cosim", path=os.path.dirname(sys.executable)) or "glider-cosim"
    return subprocess.run([exe, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, check=False)  # fmt: skip


def _toml_block(text: str) -> str:
    (block,) = re.findall(r"```toml\n(.*?)\n```", text, flags=re.S)
    return block + "\n"


def test_the_own_controller_scenario_runs_as_written(tmp_path):
    """The README's scenario with a controller that is not ours (a P law written with
    pythonfmu, tests/integration/fmus_src/SwapTestController.py) saved as the file name
    the README uses; ``glider-cosim run my-controller.toml`` as the README says."""
    from glider_cosim.fmus.python import build_slave_fmu

    block = _toml_block(README[README.index("## Test your own controller") :])
    (name,) = re.findall(r'^controller = "([^"]+)"', block, flags=re.M)
    built = build_slave_fmu(SRC / "SwapTestController.py", tmp_path / "build")
    shutil.copy(built, tmp_path / name)
    (tmp_path / "my-controller.toml").write_text(block)
    command = re.search(r"`(glider-cosim run my-controller\.toml)`", README).group(1)
    proc = _cli(shlex.split(command)[1:], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "outcome: settled" in proc.stdout, proc.stdout
    assert (tmp_path / "out" / "my-controller" / "results.csv").is_file()


def tour_lines() -> list[list[str]]:
    block = re.findall(r"```sh\n(.*?)\n```", README[README.index("## A tour") :], flags=re.S)[0]
    return [shlex.split(ln.split("#")[0]) for ln in block.splitlines()]


def test_every_tour_line_exits_0(tmp_path):
    """In order, in one empty folder (the verify line reads what the build line wrote)."""
    failed = []
    for args in tour_lines():
        assert args[0] == "glider-cosim"
        proc = _cli(args[1:], tmp_path)
        if proc.returncode != 0:
            failed.append(f"{shlex.join(args)}: exit {proc.returncode}: {proc.stderr[-500:]}")
    assert failed == []
    assert (tmp_path / "glider.ssp").is_file() and (tmp_path / "glider.fmu").is_file()
