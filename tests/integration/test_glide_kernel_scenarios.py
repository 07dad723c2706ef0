"""The run's metrics by the C kernel (cosim/runner/glidemetrics.c) are numpy's, bit for
bit, on every shipped scenario's trajectory (issue 48): the native flavor for each, the
Python flavor for those the kernel computes itself."""

from __future__ import annotations

import pytest

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
    if m["outcome"] in ("settled", "tumbling", "stopped", None):
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
