"""A native run from the CLI imports numpy through none of our modules (issue 48): numpy
costs about 50 ms of a run's start, and the run's recorders and metrics do without it."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.integration

#: refuses ``import numpy`` (and its submodules) in a module of glider_cosim, whether
#: numpy was imported before or not (a finder would only see the first import); what
#: our dependencies import is theirs
GUARD = r"""
import builtins, sys

_import = builtins.__import__

def guarded(name, globals=None, locals=None, fromlist=(), level=0):
    importer = (globals or {}).get("__name__", "")
    if level == 0 and (name == "numpy" or name.startswith("numpy.")) and (
            importer == "glider_cosim" or importer.startswith("glider_cosim.")):
        raise ImportError(f"{importer} imports numpy")
    return _import(name, globals, locals, fromlist, level)

builtins.__import__ = guarded
from glider_cosim.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize(
    ("scenario", "status"), [("default", "settled"), ("sec53-literal", "stopped")]
)  # the stopped one stalls: the metrics of a run that ended early
def test_a_native_cli_run_needs_numpy_in_none_of_our_modules(
    tmp_path, native_dir, scenario, status
):
    out = tmp_path / "run"
    args = ["run", scenario, "--fmu-dir", str(native_dir), "--no-plots", "--out", str(out)]
    env = {**os.environ, "GLIDER_COSIM_PROGRESS": "off"}
    proc = subprocess.run([sys.executable, "-c", GUARD, *args], capture_output=True,
                          text=True, env=env, timeout=300)  # fmt: skip
    assert "imports numpy" not in proc.stderr, proc.stderr[-3000:]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["outcome"] == status, (metrics["outcome"], proc.stderr[-2000:])
    assert (out / "results.csv").stat().st_size > 1000
