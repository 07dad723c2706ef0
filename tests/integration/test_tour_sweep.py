"""The README tour's sweep line, run exactly as written: it exits 0 and shows the story
(the gains below the sampled loop's stability limit ring on, those above it settle)."""

from __future__ import annotations

import csv
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

ROOT = Path(__file__).parents[2]
CLI = "from glider_cosim.cli import console_main; console_main()"


def tour_sweep_line() -> str:
    """The one ``glider-cosim sweep`` line of the README's "## A tour" block, without its
    comment."""
    readme = (ROOT / "README.md").read_text()
    tour = readme[readme.index("## A tour") :]
    block = re.search(r"```sh\n(.*?)\n```", tour, flags=re.S).group(1)
    (line,) = [ln.split("#")[0].strip() for ln in block.splitlines()
               if ln.startswith("glider-cosim sweep")]  # fmt: skip
    return line


def test_the_tour_sweep_runs_native_and_exits_0(native_dir, tmp_path):
    """Run in an empty folder with the session's FMU cache (``$GLIDER_COSIM_CACHE``, where
    ``native_dir`` built them): no option added to the README's words."""
    from glider_cosim.studies.analysis import stable_kc_ranges
    from glider_plant.params import GliderParams

    args = shlex.split(tour_sweep_line())
    assert args[:2] == ["glider-cosim", "sweep"]
    assert args[args.index("--flavor") + 1] == "native"
    p = subprocess.run([sys.executable, "-c", CLI, *args[1:]], cwd=tmp_path, env=dict(os.environ),
                       capture_output=True, text=True, timeout=600)  # fmt: skip
    assert p.returncode == 0, p.stdout + p.stderr
    assert "Traceback" not in p.stderr
    with open(tmp_path / "out" / "sweep" / "sweep.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows and all(r["status"] == "ok" for r in rows)
    settles = {float(r["controller.K_c"]): r["outcome"] == "settled" for r in rows}
    # the story: unsettled below the limit `glider-cosim analyze` computes (6.22, the
    # sampled loop with the observer), settled above it; both sides in the grid
    limit = stable_kc_ranges(GliderParams())["sampled_with_observer"][0]
    assert any(k < limit for k in settles) and any(k > limit for k in settles)
    assert [k for k, s in settles.items() if s != (k > limit)] == []
    assert (tmp_path / "out" / "sweep" / "settling_vs_effort.png").is_file()
