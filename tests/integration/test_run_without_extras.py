"""The core alone runs (issue 53): without bokeh (the ``pages`` extra) ``glider-cosim run``
writes its results and PNGs and says in one note that plots.html needs the extra; without
Dask, wasmtime, libcosimpy, fmu-manipulation-toolbox and ecospy a run does not miss them.
A missing package is simulated by blocking its import in the run's process."""

from __future__ import annotations

import subprocess
import sys

import pytest

from glider_cosim.extras import EXTRAS

pytestmark = pytest.mark.integration

#: the run's command line in a process where the named modules cannot be imported
BLOCKED = """
import sys
for name in sys.argv[1].split(","):
    sys.modules[name] = None
sys.argv = ["glider-cosim", *sys.argv[2:]]
from glider_cosim.cli import console_main
console_main()
"""


def _run(blocked: list[str], *argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", BLOCKED, ",".join(blocked), "run", *argv],
                          capture_output=True, text=True, timeout=600)  # fmt: skip


def test_a_run_without_bokeh_writes_its_pngs_and_says_the_page_needs_the_extra(fmu_dir, tmp_path):
    out = tmp_path / "run"
    p = _run(["bokeh"], "--out", str(out), "--fmu-dir", str(fmu_dir), "--stop-time", "5")
    assert p.returncode == 0, p.stderr
    assert p.stderr.splitlines() == [
        f"run: drawing the plots into {out}",
        "glider-cosim: note: plots.html not written (needs bokeh: pip install "
        "'glider-cosim[pages]'); the run's results and PNGs are kept",
    ]
    assert len(list(out.glob("*.png"))) == 5 and not (out / "plots.html").exists()
    assert (out / "results.csv").stat().st_size > 0 and (out / "metrics.json").is_file()


def test_a_run_without_any_extra_runs_as_with_them(fmu_dir, tmp_path):
    every = [m for modules in EXTRAS.values() for m in modules]
    bare, full = tmp_path / "bare", tmp_path / "full"
    p = _run(every, "--out", str(bare), "--fmu-dir", str(fmu_dir), "--no-plots", "--stop-time", "5")
    assert (p.returncode, p.stderr) == (0, ""), p.stderr
    q = _run([], "--out", str(full), "--fmu-dir", str(fmu_dir), "--no-plots", "--stop-time", "5")
    assert q.returncode == 0, q.stderr
    assert (bare / "results.csv").read_bytes() == (full / "results.csv").read_bytes()
