"""A run's start done once (issue 48), on the real FMUs: the CLI checks the cache's set
once, and a run's table is the one it wrote, without reading ``results.csv`` back."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from glider_cosim.cli.main import main
from glider_cosim.fmus import folders
from glider_cosim.runner import run as run_module
from glider_cosim.runner import simulate

pytestmark = pytest.mark.integration


def test_a_cli_run_checks_the_cache_set_once(tmp_path, monkeypatch, native_dir):
    calls = []
    real = folders.build_all

    def counted(*args, **kwargs):
        calls.append(args[0] if args else kwargs.get("out"))
        return real(*args, **kwargs)

    monkeypatch.setattr(folders, "build_all", counted)
    monkeypatch.setattr(run_module, "build_all", counted)
    assert main(["run", "--flavor", "native", "--no-plots", "--stop-time", "2",
                 "--out", str(tmp_path / "run")]) == 0  # fmt: skip
    assert len(calls) == 1, calls
    calls.clear()  # a folder given: built there by the run, as before
    assert main(["run", "--fmu-dir", str(native_dir), "--no-plots", "--stop-time", "2",
                 "--out", str(tmp_path / "run2")]) == 0  # fmt: skip
    assert [str(c) for c in calls] == [str(native_dir)]


def test_a_run_keeps_the_table_it_writes(tmp_path, monkeypatch, native_dir):
    def no_reading(*args, **kwargs):
        raise AssertionError("results.csv read back")

    monkeypatch.setattr(np, "loadtxt", no_reading)
    result = simulate("default", tmp_path, fmu_dir=native_dir, build=False, plots=False,
                      stop_time=5.0)  # fmt: skip
    monkeypatch.undo()
    written = np.loadtxt(tmp_path / "results.csv", delimiter=",", skiprows=1, ndmin=2)
    assert result.data.shape == (251, len(result.columns))
    assert result.data.tobytes() == written.tobytes()


#: a whole CLI run in a fresh interpreter, then the modules it imported
RUN_AND_LIST = """
import json, sys
from glider_cosim.cli.main import main
code = main(sys.argv[1:])
print(json.dumps(sorted(sys.modules)))
sys.exit(code)
"""


@pytest.mark.parametrize("flavor", ["native", "python"])
def test_a_run_of_the_cache_is_an_fmpy_master(tmp_path, native_dir, fmu_dir, flavor):
    # every FMU is read by fmpy.read_model_description and runs on fmpy's FMU2Slave; our
    # own binding and description reader are gone (issue 53)
    out = tmp_path / "run"
    p = subprocess.run([sys.executable, "-c", RUN_AND_LIST, "run", "--no-plots", "--flavor",
                        flavor, "--stop-time", "5", "--out", str(out)],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    modules = {m.split(".")[0] for m in json.loads(p.stdout.splitlines()[-1])}
    assert {"fmpy", "lxml"} <= modules
    assert not {"glider_cosim.master.binding", "glider_cosim.inputs.description"} & set(
        json.loads(p.stdout.splitlines()[-1])
    )
    assert "glider_cosim" in modules and (out / "results.csv").is_file()
    assert (out / "metrics.json").is_file() and "wrote" in p.stdout
