"""The Python recipe of docs/how-to/webassembly.md runs as written: the plant's component
through wasmtime alone, its numbers those of the same FMU's native library (fmpy's FMI 3
API, the same calls) within 1e-15 (WASI libc's libm against glibc's)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi3 import FMU3Slave

from glider_cosim.fmus.folders import prepare_fmus

pytestmark = pytest.mark.integration
PAGE = Path(__file__).parents[2] / "docs" / "how-to" / "webassembly.md"


def native_plant(fmu: Path) -> tuple[float, float]:
    """The recipe's calls on the native library."""
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    where = extract(str(fmu))
    try:
        s = FMU3Slave(guid=md.guid, unzipDirectory=where, instanceName="plant",
                      modelIdentifier=md.coSimulation.modelIdentifier)  # fmt: skip
        s.instantiate()
        s.enterInitializationMode(startTime=0.0)
        s.exitInitializationMode()
        for k in range(500):
            s.setFloat64([vr["delta_cmd"]], [0.0])
            s.doStep(k * 0.02, 0.02)
        theta_g, v = s.getFloat64([vr["theta_g"], vr["V"]])
        s.terminate()
        s.freeInstance()
        return theta_g, v
    finally:
        shutil.rmtree(where, ignore_errors=True)


def test_the_recipe_runs_as_written(tmp_path):
    (code,) = re.findall(r"^```python\n(.*?)^```", PAGE.read_text(), re.M | re.S)
    folder = tmp_path / "fmus" / "fmi3" / "native"
    shutil.copytree(prepare_fmus(None, "native", 3, host_only=True), folder)
    (tmp_path / "recipe.py").write_text(code)
    p = subprocess.run([sys.executable, "recipe.py"], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr
    m = re.fullmatch(r"t = 10 s: theta_g = (\S+) rad, V = (\S+) m/s\n", p.stdout)
    assert m, p.stdout
    theta_g, v = native_plant(folder / "GliderPlant.fmu")
    assert abs(float(m[1]) - theta_g) <= 1e-15 and abs(float(m[2]) - v) <= 1e-15
    assert theta_g != 0.0 and abs(v - 0.2) > 1e-3  # it moved
