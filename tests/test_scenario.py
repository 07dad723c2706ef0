"""Scenario parsing: shipped scenarios load; malformed ones name the file and key."""

from __future__ import annotations

import math

import pytest

from glider_cosim.scenarios.fields import ScenarioError
from glider_cosim.scenarios.scenario import load_scenario, shipped_scenarios


def test_shipped_scenarios_load():
    names = shipped_scenarios()
    assert {"default", "sec53-protocol", "sec53-literal"} <= set(names)
    for n in names:
        assert load_scenario(n).name == n


def test_default_is_sec33_with_a_stable_gain():
    sc = load_scenario(None)
    assert sc.stop_time == 60.0 and sc.step == 0.02 and sc.coupling == "gauss-seidel"
    assert sc.parameters["plant"]["theta_g_0"] == pytest.approx(math.radians(-35.0))
    assert sc.parameters["controller"] == {"law": 1, "K_c": 10.0}


def write(tmp_path, text):
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("stop_time = ", r"s.toml: not valid TOML"),
        ("stoptime = 5", r"s.toml: unknown key 'stoptime': expected one of"),
        ("stop_time = 'long'", r"s.toml: key 'stop_time': 'long' is not a number"),
        ("stop_time = -5.0", r"s.toml: key 'stop_time': -5.0 is invalid: expected a number > 0"),
        ("step = 0", r"key 'step': 0 is invalid: expected a number > 0"),
        ("coupling = 'gs'", r"key 'coupling': 'gs' is invalid: expected 'gauss-seidel' or"),
        ("plant = 3", r"key 'plant': expected a table"),
        ("[plant]\nV_0 = 'fast'", r"key 'plant.V_0': 'fast' is not a number"),
        ("[controller]\nlaw = 'pid'", r"key 'controller.law': 'pid' is invalid"),
        ("[fmus]\nplant = 'missing.fmu'", r"key 'fmus.plant': .*missing.fmu does not exist"),
        ("[[disturbance]]\ntarget = 'plant.F_x'\nkind = 'ramp'", r"disturbance\[0\].kind"),
        ("[[disturbance]]\ntarget = 'plant.F_x'\ntime = -1.0", r"disturbance\[0\].time: -1.0"),
        ("[[disturbance]]\ntarget = 'plant.F_x'\nkind='pulse'", r"duration: 0.0 is invalid"),
        ("[[event]]\nwhen = 'z is deep'\nset = {a = 1}", r"event\[0\].when: 'z is deep'"),
        ("[[event]]\nwhen = 'time >= 1'", r"event\[0\].set: expected at least one"),
        ("[[event]]\nwhen = 'time >= 1'\nset={a=1}\nexec='x'", r"event\[0\]: unknown key 'exec'"),
    ],
)
def test_malformed_scenarios_name_file_and_key(tmp_path, text, message):
    with pytest.raises(ScenarioError, match=message) as err:
        load_scenario(write(tmp_path, text))
    assert "\n" not in str(err.value).strip() or "TOML" in str(err.value)


def test_missing_file(tmp_path):
    with pytest.raises(ScenarioError, match=r"nope.toml: scenario file does not exist"):
        load_scenario(tmp_path / "nope.toml")


def test_degrees_events_and_disturbances(tmp_path):
    sc = load_scenario(
        write(
            tmp_path,
            """
[plant]
theta_g_0 = "-30 deg"
[[disturbance]]
target = "plant.F_z"
kind = "pulse"
time = 5.0
duration = 1.0
value = 0.2
[[event]]
when = "plant.z >= 1.5"
delay = 0.5
set = { "controller.law" = "pi", "controller.K_P" = 3 }
""",
        )
    )
    assert sc.parameters["plant"]["theta_g_0"] == pytest.approx(-math.pi / 6)
    d = sc.disturbances[0]
    assert (d.at(4.99), d.at(5.0), d.at(5.99), d.at(6.0)) == (0.0, 0.2, 0.2, 0.0)
    ev = sc.events[0]
    assert (ev.variable, ev.op, ev.threshold, ev.delay) == ("plant.z", ">=", 1.5, 0.5)
    assert ev.actions == {"controller.law": 3, "controller.K_P": 3}


def test_set_overrides_parse_numbers_degrees_and_laws():
    from glider_cosim.scenarios.overrides import parse_sets

    out = parse_sets(["controller.K_c=6", "plant.theta_g_0=-30 deg", "controller.law=pi",
                      "plant.noise_seed=4"])  # fmt: skip
    assert out == {"controller.K_c": 6, "plant.theta_g_0": pytest.approx(-math.pi / 6),
                   "controller.law": 3, "plant.noise_seed": 4}  # fmt: skip
    with pytest.raises(ScenarioError, match=r"--set 'K_c=6': expected INSTANCE.NAME=VALUE"):
        parse_sets(["K_c=6"])
    with pytest.raises(ScenarioError, match=r"--set 'plant.V_0=fast'.*'fast' is not a number"):
        parse_sets(["plant.V_0=fast"])


def test_with_observer_false_needs_state_feedback(tmp_path):
    sc = load_scenario(write(tmp_path, 'feedback = "state"\nwith_observer = false\n'))
    assert sc.observer is False
    with pytest.raises(ScenarioError, match=r"key 'with_observer': false needs feedback"):
        load_scenario(write(tmp_path, "with_observer = false\n"))
    with pytest.raises(ScenarioError, match=r"key 'with_observer': expected true or false"):
        load_scenario(write(tmp_path, 'with_observer = "no"\n'))


def test_f_sample_follows_the_step_unless_set():
    from glider_cosim.scenarios.sampling import with_sampling

    params = {"controller": {"K_c": 10.0}}
    out = with_sampling(params, 0.005)
    assert out["observer"]["f_sample"] == pytest.approx(200.0)
    assert "observer" not in params  # not modified
    assert "observer" not in with_sampling(params, 0.005, observer=False)


def test_explicit_f_sample_mismatch_is_warned_in_one_line():
    import warnings

    from glider_cosim.scenarios.sampling import SamplingMismatchWarning, with_sampling

    with pytest.warns(SamplingMismatchWarning, match=r"s\.toml: observer\.f_sample = 50 Hz") as w:
        out = with_sampling({"observer": {"f_sample": 50.0}}, 0.01, "s.toml")
    assert out["observer"]["f_sample"] == 50.0
    assert "\n" not in str(w[0].message)
    assert "1/step = 100 Hz" in str(w[0].message)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with_sampling({"observer": {"f_sample": 100.0}}, 0.01)  # consistent: silent


def test_a_step_too_long_for_the_pre_filter_is_refused():
    from glider_cosim.scenarios.sampling import with_sampling

    with pytest.raises(ScenarioError, match=r"step 0\.1 s samples .* at 10 Hz.*below 5 Hz"):
        with_sampling({}, 0.1, "s.toml")
    assert with_sampling({"observer": {"f_cutoff": 2.0}}, 0.1)["observer"]["f_sample"] == 10.0
    off = with_sampling({"observer": {"filter_enabled": False}}, 0.1)
    assert off["observer"]["f_sample"] == pytest.approx(10.0)


def test_a_swapped_in_observer_gets_no_f_sample(tmp_path):
    from glider_cosim.scenarios.sampling import has_our_observer
    from glider_cosim.scenarios.scenario import parse_scenario

    assert has_our_observer(load_scenario(None))
    assert not has_our_observer(load_scenario("fig2-open-loop"))  # no observer
    fmu = tmp_path / "Other.fmu"
    fmu.write_bytes(b"")
    sc = parse_scenario({"fmus": {"observer": str(fmu)}})
    assert not has_our_observer(sc)
