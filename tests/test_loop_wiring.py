"""The loop's wiring of a swapped-in controller or estimator (issue 54 item 1), on names
alone: :func:`glider_cosim.scenarios.system.loop_wiring`, and the units that
:func:`glider_cosim.verify.loop.interface_check` reads."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from glider_cosim.master import SystemSpecError
from glider_cosim.scenarios.system import default_connections, loop_wiring
from glider_cosim.verify.cases import VerifyInputError
from glider_cosim.verify.loop import interface_check

PLANT = {"delta_cmd": "input", "theta_meas": "output", "V": "output", "theta_g": "output",
         "z": "output"}  # fmt: skip
OBSERVER = {"theta_meas": "input", "delta_cmd": "input", "V_hat": "output",
            "theta_g_hat": "output"}  # fmt: skip
CONTROLLER = {"V_hat": "input", "theta_g_hat": "input", "delta_cmd": "output"}
NAMES = {"plant": "GliderPlant", "observer": "GliderObserver", "controller": "C"}


def wire(controller=CONTROLLER, observer=OBSERVER, swapped=("controller",), driven=(), names=NAMES):
    variables = {"plant": PLANT, "observer": observer, "controller": controller}
    return loop_wiring(default_connections(), variables, names, set(swapped), set(driven))


def test_our_interface_is_wired_as_before_without_a_note():
    conns, notes, left = wire()
    assert conns == default_connections() and notes == [] and left == []


def test_the_readme_interface_drops_v_hat_with_one_note():
    conns, notes, left = wire({"theta_g_hat": "input", "delta_cmd": "output"})
    assert ("observer.V_hat", "controller.V_hat") not in conns
    assert notes == ["controller ('C'): not connected: observer.V_hat (no optional input V_hat)"]
    assert left == []


def test_other_inputs_by_name_the_estimate_first_else_held():
    ctrl = {"theta_g_hat": "input", "delta_cmd": "output", "z": "input", "V_hat": "input",
            "k": "input", "theta_meas": "input"}  # fmt: skip
    conns, notes, left = wire(ctrl, driven={"controller.theta_meas"})
    assert ("plant.z", "controller.z") in conns
    assert not any(dst == "controller.theta_meas" for _, dst in conns)  # driven by the scenario
    assert left == ["controller.k"]
    assert notes == [
        "controller ('C'): not connected: input k, left at its start value (no output k in "
        "the loop); connected by name: plant.z -> controller.z"
    ]


def test_required_variables_are_named_with_causality_and_unit():
    with pytest.raises(SystemSpecError, match=r"controller \('C'\) lacks what the loop requires "
                       r"of the controller: theta_g_hat \(input, rad\) \(docs/"):  # fmt: skip
        wire({"delta_cmd": "output", "V_hat": "input"})


def test_an_estimator_without_v_hat_serves_a_controller_without_it_only():
    est = {"theta_meas": "input", "theta_g_hat": "output"}
    names = {**NAMES, "observer": "E"}
    with pytest.raises(SystemSpecError, match=r"observer \('E'\) has no output V_hat \(m/s\)"):
        wire(observer=est, swapped=("observer",), names=names)
    conns, notes, _ = wire({"theta_g_hat": "input", "delta_cmd": "output"}, est,
                           ("observer", "controller"))  # fmt: skip
    assert ("observer.theta_g_hat", "controller.theta_g_hat") in conns
    assert len(notes) == 2


def _md(**units):
    variables = [SimpleNamespace(name=n, causality=c, unit=units.get(n), declaredType=None)
                 for n, c in CONTROLLER.items()]  # fmt: skip
    return SimpleNamespace(modelVariables=variables, modelName="C")


def test_units_are_checked_where_declared():
    assert interface_check(_md(), "controller", "C.fmu").passed
    check = interface_check(_md(theta_g_hat="deg"), "controller", "C.fmu")
    assert not check.passed and check.detail == "theta_g_hat in deg, expected rad"
    md = _md()
    md.modelVariables = md.modelVariables[1:2]
    with pytest.raises(VerifyInputError, match="delta_cmd"):
        interface_check(md, "controller", "C.fmu")
