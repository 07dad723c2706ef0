"""The libcosim recipe of docs/how-to/use-the-fmus.md ends cleanly (issue 28 point 7):
libcosim's log level is set, and the Python flavor's instances that libcosim terminates
and frees after the interpreter has finalized say nothing."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from glider_cosim.interop.ssp_export import export_ssp

pytestmark = pytest.mark.integration
PAGE = Path(__file__).parents[2] / "docs" / "how-to" / "use-the-fmus.md"


def recipe() -> str:
    """The libcosimpy code block of the page (indented under its list item)."""
    blocks = re.findall(r"^( *)```python\n(.*?)^\1```", PAGE.read_text(), re.M | re.S)
    code = [b for indent, b in blocks if "CosimExecution" in b]
    assert len(code) == 1, "expected one libcosimpy block in use-the-fmus.md"
    indent = re.match(r" *", code[0]).group(0)
    return "".join(line.removeprefix(indent) for line in code[0].splitlines(keepends=True))


@pytest.mark.parametrize("flavor", ["python", "native"])
def test_libcosim_recipe_prints_only_its_result(flavor, request, tmp_path):
    pytest.importorskip("libcosimpy")
    folder = request.getfixturevalue("fmu_dir" if flavor == "python" else "native_dir")
    export_ssp(tmp_path / "glider.ssp", None, folder)
    (tmp_path / "recipe.py").write_text(recipe())
    p = subprocess.run([sys.executable, "recipe.py"], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr
    out = p.stdout + p.stderr
    for level in ("[error]", "[warning]", "[info]", "[debug]", "[trace]"):
        assert level not in out, out
    assert re.fullmatch(r"theta_g\(20 s\) = -?\d+\.\d{6} rad\n", p.stdout), out
