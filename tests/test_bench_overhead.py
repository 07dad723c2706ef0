"""bench/overhead_profile.py: how sampled functions are split into the parts it reports."""

from __future__ import annotations

import sys

import pytest
from test_housekeeping import _bench_module


@pytest.fixture(scope="module")
def bench():
    return _bench_module("overhead_profile")


FILES = {
    "GliderPlant.so": {
        "glider_plant_step": "/src/glider_plant/plant_model.c",
        "step": "/src/glider_plant/plant_fmu.c",
        "nat_quick_real": "/src/fmi/backend_native.c",
        "glider_op_access": "/src/fmi/fmi_layer.c",
        "fmi2GetReal": "/src/fmi/fmi2_layer.c",
    }
}
MODEL = {"glider_plant_step", "observer_step"}


@pytest.mark.parametrize(
    ("dso", "sym", "part"),
    [
        ("GliderPlant.so", "glider_plant_step", "models"),
        ("GliderPlant.so", "step", "glue"),
        ("GliderPlant.so", "nat_quick_real", "backend"),
        ("GliderPlant.so", "glider_op_access", "layer"),
        ("GliderPlant.so", "fmi2GetReal", "layer"),
        ("libm.so.6", "__sin_fma", "libm"),
        ("fastloop.so", "glider_run", "master"),
        ("monolithic.so", "glider_mono_run", "master"),
        ("monolithic.so", "observer_step", "models"),
        ("libpython3.11.so.1.0", "_PyEval_EvalFrameDefault", ""),
    ],
)
def test_each_function_goes_to_its_part(bench, dso, sym, part):
    assert bench._part(dso, sym, FILES, MODEL) == part


def test_without_perf_it_says_what_is_missing(bench, monkeypatch):
    monkeypatch.setattr(bench.shutil, "which", lambda name: None)
    monkeypatch.setattr(sys, "argv", ["overhead_profile.py"])
    with pytest.raises(SystemExit, match="perf is not installed: expected `perf` on PATH"):
        bench.main()
