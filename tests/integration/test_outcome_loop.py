"""Outcomes of the glider loop detected from its trajectory (Figs. 3-4 scenario)."""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

from glider_cosim.runner import simulate
from glider_cosim.scenarios.overrides import apply_overrides
from glider_cosim.scenarios.scenario import load_scenario

pytestmark = pytest.mark.integration


def _run(fmu_dir, k_c: float):
    sc = apply_overrides(load_scenario("fig3-4-kc"), {"controller.K_c": k_c})
    return simulate(sc, None, fmu_dir=fmu_dir, build=False).metrics


def test_k_c_6_near_the_sampled_limit_is_a_limit_cycle_not_settled(fmu_dir):
    """Its last samples fall in the band at a zero crossing; it must not count."""
    m = _run(fmu_dir, 6.0)
    assert m["settling_time_s"] is None
    assert m["outcome"] == "limit cycle"
    assert 1.0 < math.degrees(m["outcome_amplitude_rad"]) < 3.0
    assert 1.5 < m["outcome_period_s"] < 2.0


def test_k_c_2_is_a_20_deg_limit_cycle(fmu_dir):
    m = _run(fmu_dir, 2.0)
    assert m["settling_time_s"] is None
    assert m["outcome"] == "limit cycle"
    assert math.degrees(m["outcome_amplitude_rad"]) == pytest.approx(20.4, abs=0.5)


def test_k_c_10_settles(fmu_dir):
    m = _run(fmu_dir, 10.0)
    assert m["outcome"] == "settled"
    assert m["settling_time_s"] == pytest.approx(10.48, abs=0.1)
    assert 60.0 - m["settling_time_s"] >= m["settling_hold_s"]


def test_cli_prints_the_outcome(fmu_dir, tmp_path):
    code = "from glider_cosim.cli import console_main; console_main()"
    args = ["run", "fig3-4-kc", "--set", "controller.K_c=6", "--no-plots", "--out",
            str(tmp_path), "--fmu-dir", str(fmu_dir)]  # fmt: skip
    p = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                       timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert "settling n/a" in p.stdout
    assert "outcome: limit cycle: amplitude 1.9" in p.stdout


@pytest.mark.parametrize(
    ("name", "overrides", "outcome"),
    [
        ("default", {}, "settled"),
        ("default", {"controller.K_c": 4.0}, "not settled"),
        ("default", {"controller.K_c": 5.0}, "limit cycle"),
        ("fig3-4-kc", {"controller.K_c": 6.0}, "limit cycle"),
        ("default", {"controller.K_c": 2.0}, "stopped"),  # the plant stalls at 9.08 s
        ("default", {"controller.K_c": 0.05}, "stopped"),  # the observer at 2.58 s
        ("fig5-6-observer-noise", {}, "settled"),
        ("fig2-open-loop", {}, "settled"),
    ],
)
def test_the_metrics_are_bit_for_bit_those_of_the_loop(native_dir, name, overrides, outcome):
    """The vectorised zero crossings (issue 31) change no metric of a real run: every
    value == the one the sample-by-sample loop gave, the failing runs' included."""
    import struct

    from outcome_reference import glide_metrics_loop

    sc = apply_overrides(load_scenario(name), overrides)
    r = simulate(sc, None, fmu_dir=native_dir, build=False)
    assert r.metrics["outcome"] == outcome
    old = glide_metrics_loop(r.columns, r.data, r.metrics["theta_ge_rad"], r.metrics["t_on_s"],
                             completed=r.status == "ok")  # fmt: skip

    def bits(v):
        return struct.pack("<d", v) if isinstance(v, float) else v

    assert {k: bits(r.metrics[k]) for k in old} == {k: bits(v) for k, v in old.items()}
