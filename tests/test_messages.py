"""The one-line message of each refused class of input, exactly (issue 21)."""

from __future__ import annotations

import pytest

from glider_cosim.cli import main
from glider_cosim.scenarios.fields import ScenarioError
from glider_cosim.scenarios.overrides import parse_sets
from glider_cosim.scenarios.scenario import parse_scenario

LAW = "expected one of 'open-loop', 'passivity', 'p', 'pi' (any case) or an integer 0..3"


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ("controller.law=PID", f"--set 'controller.law=PID': 'PID' is invalid: {LAW}"),
        ("controller.law=7", f"--set 'controller.law=7': '7' is invalid: {LAW}"),
        ("plant.V_0=fast",
         "--set 'plant.V_0=fast': 'fast' is not a number: expected a number (m/s) or "
         "'X m/s'"),
        ("plant.theta_g_0=x", "--set 'plant.theta_g_0=x': 'x' is not a number: expected a number "
         "(rad) or 'X deg'"),
        ("controller.K_c=a", "--set 'controller.K_c=a': 'a' is not a number: expected a number"),
        ("observer.f_sample=x",
         "--set 'observer.f_sample=x': 'x' is not a number: expected a number (Hz) or 'X Hz'"),
        ("plant.not_ours=x", "--set 'plant.not_ours=x': 'x' is not a number: expected a number"),
    ],
)  # fmt: skip
def test_set_messages(item, message):
    with pytest.raises(ScenarioError) as err:
        parse_sets([item])
    assert str(err.value) == message


@pytest.mark.parametrize("text", ["P", "p", " Pi ", "PI", "Open-Loop", "PASSIVITY", "2"])
def test_law_names_any_case(text):
    value = parse_sets([f"controller.law={text}"])["controller.law"]
    assert value == {"p": 2, "pi": 3, "open-loop": 0, "passivity": 1, "2": 2}[text.strip().lower()]


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        ({"coupling": "gs"},
         "s.toml: key 'coupling': 'gs' is invalid: expected 'gauss-seidel' or 'jacobi' (any case)"),
        ({"feedback": "full"},
         "s.toml: key 'feedback': 'full' is invalid: expected 'observer' or 'state' (any case)"),
        ({"controller": {"law": "PID"}}, f"s.toml: key 'controller.law': 'PID' is invalid: {LAW}"),
        ({"controller": {"law": 2.5}}, f"s.toml: key 'controller.law': 2.5 is invalid: {LAW}"),
        ({"event": [{"when": "time >= 1", "set": {"controller.law": "pd"}}]},
         f"s.toml: key event[0].set.controller.law: 'pd' is invalid: {LAW}"),
        ({"plant": {"V_0": "fast"}},
         "s.toml: key 'plant.V_0': 'fast' is not a number: expected a number (m/s) or "
         "'X m/s'"),
        ({"plant": {"theta_g_0": "steep"}},
         "s.toml: key 'plant.theta_g_0': 'steep' is not a number: expected a number (rad) or "
         "'X deg'"),
        ({"stop_time": "long"}, "s.toml: key 'stop_time': 'long' is not a number: expected a "
         "number"),
    ],
)  # fmt: skip
def test_scenario_messages(doc, message):
    with pytest.raises(ScenarioError) as err:
        parse_scenario(doc, "s.toml")
    assert str(err.value) == message


def test_enumerations_any_case():
    sc = parse_scenario({"coupling": "Jacobi", "feedback": "STATE", "controller": {"law": "Pi"}})
    assert (sc.coupling, sc.feedback, sc.parameters["controller"]["law"]) == ("jacobi", "state", 3)


def test_cli_coupling_message(capsys):
    with pytest.raises(SystemExit) as ex:
        main(["run", "--coupling", "gs"])
    assert ex.value.code == 2
    assert (
        capsys.readouterr()
        .err.strip()
        .endswith(
            "argument --coupling: invalid choice: 'gs' (choose from 'gauss-seidel', 'jacobi')"
        )
    )
