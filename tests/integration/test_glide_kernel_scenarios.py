"""The run's metrics by the C kernel (cosim/runner/glidemetrics.c) are numpy's, bit for
bit, on every shipped scenario's trajectory (issue 48): the native flavor for each, the
Python flavor for three (settled, stopped, limit cycle)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from system_tools import require_tool, tool_missing

from glider_cosim.runner import metrics as metrics_module
from glider_cosim.runner import simulate
from glider_cosim.runner.metrics import _glide_metrics_c, glide_metrics
from glider_cosim.scenarios.scenario import shipped_scenarios

pytestmark = pytest.mark.integration


def bits(value):
    if isinstance(value, float):
        return ("float", value.hex())
    if isinstance(value, list | tuple):
        return (type(value).__name__, [bits(v) for v in value])
    return (type(value).__name__, value)


def numpy_metrics(result) -> dict:
    """:func:`glide_metrics` (numpy) of the run's table, as the run computed it before."""
    m, d = result.metrics, result.data
    cols = result.columns
    t, th, dc = (d[:, k].copy() for k in (0, cols.index("plant.theta_g"),
                                          cols.index("controller.delta_cmd")))  # fmt: skip
    return glide_metrics(t, th, dc, m["theta_ge_rad"], m["t_on_s"], completed=result.status == "ok")


@pytest.mark.parametrize("name", shipped_scenarios())
def test_every_shipped_scenario_has_the_numpy_metrics(name, native_dir, fmu_dir):
    result = simulate(name, fmu_dir=native_dir, build=False, plots=False)
    want = numpy_metrics(result)
    for k, v in want.items():
        assert bits(result.metrics[k]) == bits(v), (name, k, result.metrics[k], v)
    cols = result.columns
    which = (0, cols.index("plant.theta_g"), cols.index("controller.delta_cmd"))
    m = result.metrics
    by_kernel = _glide_metrics_c(result.data, which, m["theta_ge_rad"], m["t_on_s"],
                                 result.status == "ok")  # fmt: skip
    assert by_kernel is not None, (name, m["outcome"])
    if name in ("default", "sec53-literal", "fig2-closed-loop"):  # the Python flavor too
        py = simulate(name, fmu_dir=fmu_dir, build=False, plots=False)
        for k, v in numpy_metrics(py).items():
            assert bits(py.metrics[k]) == bits(v), (name, "python", k)


def test_without_the_kernel_the_run_has_the_same_metrics(native_dir, monkeypatch):
    with_kernel = simulate("default", fmu_dir=native_dir, build=False, plots=False).metrics
    monkeypatch.setattr(metrics_module, "_KERNEL", [None])
    without = simulate("default", fmu_dir=native_dir, build=False, plots=False).metrics
    assert [bits(v) for k, v in with_kernel.items() if k != "run"] == [
        bits(v) for k, v in without.items() if k != "run"
    ]


KERNEL = Path(metrics_module.__file__).with_name("glidemetrics.c")

UNDER_ASAN = r"""
import ctypes, sys
sys.path.insert(0, sys.argv[2])
from glider_cosim.runner import metrics as M
lib = ctypes.CDLL(sys.argv[1])
M._KERNEL[:] = []
import glider_cosim.master.fastloop as fastloop
fastloop.library = lambda **kw: lib  # the sanitised build in place of the helper
import test_glide_kernel as T
T.test_the_kernel_gives_the_numpy_metrics_bit_for_bit()
T.test_the_estimation_rms_is_numpys_bit_for_bit()
T.test_a_value_not_finite_is_left_to_numpy()
print("checked", M._KERNEL[0] is lib)
"""


def test_the_kernel_is_warning_free_and_clean_under_asan_and_ubsan(tmp_path):
    """gcc -Wall -Wextra -Werror; then the bit-for-bit tests with the kernel built with
    AddressSanitizer and UndefinedBehaviorSanitizer (both runtimes preloaded into Python)."""
    gcc = require_tool("gcc")
    so = tmp_path / "glidemetrics_asan.so"
    subprocess.run([gcc, "-std=c99", "-O1", "-g", "-Wall", "-Wextra", "-Werror",
                    "-ffp-contract=off", "-fsanitize=address,undefined", "-fno-omit-frame-pointer",
                    "-fPIC", "-shared", str(KERNEL), "-o", str(so), "-lm"],
                   check=True, capture_output=True, text=True)  # fmt: skip
    runtimes = [
        subprocess.run(
            [gcc, f"-print-file-name={n}"], capture_output=True, text=True
        ).stdout.strip()
        for n in ("libasan.so", "libubsan.so")
    ]
    if not all(Path(r).is_file() for r in runtimes):
        tool_missing("gcc's ASan/UBSan runtimes are not installed (libasan, libubsan)")
    env = {**os.environ, "LD_PRELOAD": " ".join(runtimes), "ASAN_OPTIONS": "detect_leaks=0",
           "UBSAN_OPTIONS": "halt_on_error=1:print_stacktrace=1"}  # fmt: skip
    tests = Path(__file__).resolve().parents[1]
    proc = subprocess.run([sys.executable, "-c", UNDER_ASAN, str(so), str(tests)],
                          capture_output=True, text=True, env=env, timeout=300)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "checked True" in proc.stdout
    assert "runtime error" not in proc.stderr and "AddressSanitizer" not in proc.stderr
