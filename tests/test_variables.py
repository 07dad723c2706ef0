"""One rule for a variable's value in words (glider_cosim.fmus.variables): the run's echo
of its overrides (units from the FMUs' model descriptions), the plots' subtitles and the
sweep's axes (units from our FMUs' tables) write a value the same way."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from glider_cosim.figures.plots import settings_text
from glider_cosim.fmus.variables import overrides_echo, unit_of_target, with_unit
from glider_cosim.inputs.check import our_table
from glider_cosim.inputs.values import parse_quantity


def _description(inst: str) -> SimpleNamespace:
    """A model description as fmpy reads one, from our FMU ``inst``'s variable table."""
    variables = [SimpleNamespace(name=v.name, unit=v.unit, declaredType=None)
                 for v in our_table(inst).values()]  # fmt: skip
    return SimpleNamespace(modelVariables=variables, unitDefinitions=[])


@pytest.mark.parametrize("inst", ["plant", "observer", "controller"])
def test_a_description_and_our_tables_give_the_same_words(inst):
    md = _description(inst)
    for name in our_table(inst):
        target = f"{inst}.{name}"
        assert unit_of_target(target, md) == unit_of_target(target)
        for value in (0.25, 3, True):
            assert with_unit(target, value, md) == with_unit(target, value)
            assert with_unit(target, value, md, both=True) == with_unit(target, value, both=True)


def test_the_forms():
    rad = next(f"plant.{n}" for n, v in our_table("plant").items() if v.unit == "rad")
    assert with_unit(rad, 1.0) == "1 rad"
    assert with_unit(rad, 1.0, both=True) == "1 rad (57.3 deg)"
    deg = parse_quantity("-30 deg")
    assert with_unit(rad, deg) == "-30 deg"
    assert with_unit(rad, deg, both=True) == "-30 deg (-0.5236 rad)"
    assert with_unit("controller.law", 3) == "pi"
    assert with_unit("controller.law", 1, both=True) == "1 (passivity)"
    assert with_unit("controller.K_c", 6) == "6"
    assert with_unit("other.x", 0.5) == "0.5" and unit_of_target("other.x") is None


def test_the_echo_and_the_subtitle_share_the_rule(tmp_path):
    rad = next(f"plant.{n}" for n, v in our_table("plant").items() if v.unit == "rad")
    overrides = {rad: 0.5, "controller.law": 3, "controller.K_c": 6}
    missing = {"plant": tmp_path / "none.fmu", "controller": tmp_path / "none.fmu"}
    echo = overrides_echo(overrides, missing)  # unreadable: our tables' units
    assert echo == f"{rad} = 0.5 rad (28.65 deg), controller.law = 3 (pi), controller.K_c = 6"
    subtitle = settings_text({"scenario": "default", "run": {"overrides": overrides}})
    assert subtitle == f"scenario default; {rad}=0.5 rad, controller.law=pi, controller.K_c=6"


def test_model_description_questions_are_asked_of_the_fmus_room():
    """The sweep's nominal values (an FMU's parameter defaults) and the run's echo come
    from ``fmus/variables.py``, not from the runner (``runner/monolithic.py``,
    ``runner/provenance.py``)."""
    from test_layout import GRAPH

    assert "glider_cosim.fmus.variables" in GRAPH["glider_cosim.sweeps.spec"]
    assert (
        not {"glider_cosim.runner.monolithic", "glider_cosim.runner.provenance"}
        & GRAPH["glider_cosim.sweeps.spec"]
    )
    assert "glider_cosim.fmus.variables" in GRAPH["glider_cosim.runner.checked"]
