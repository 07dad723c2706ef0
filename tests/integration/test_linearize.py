"""The plant FMU's directional derivatives (FMI 2 and 3, both flavors): exact (the model's
Jacobian bit for bit), equal to central differences through the FMU itself, refused
where they do not apply, and ``glider-cosim analyze --from-fmu`` built on them."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

from glider_cosim.master.instance import _extracted
from glider_cosim.studies.analysis import K_C_LIST, analyze, closed_loop_matrix
from glider_cosim.studies.linearize import (
    LinearizationError,
    linearize,
    provides_directional_derivatives,
)
from glider_plant.jacobian import PLANT_INPUTS, PLANT_STATES, plant_derivatives, plant_jacobian
from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

pytestmark = pytest.mark.integration

#: a point away from the equilibrium: tail deflected, a command, every disturbance on
POINT = {"V_0": 0.31, "theta_g_0": -0.52, "alpha_0": 0.043, "omega2_0": 0.021, "x_0": 3.0,
         "z_0": 1.5, "delta_0": 0.12, "delta_cmd": -0.2, "F_x": 0.3, "F_z": -0.4, "M_y": 0.05,
         "tau_servo": 0.02, "m": 12.0}  # fmt: skip


@pytest.fixture(scope="module", params=["python-2", "native-2", "python-3", "native-3"])
def plant(request, fmi3_dirs) -> Path:
    flavor, fmi = request.param.split("-")
    if fmi == "3":
        return fmi3_dirs[flavor] / "GliderPlant.fmu"
    return request.getfixturevalue("fmu_dir" if flavor == "python" else "native_dir") / (
        "GliderPlant.fmu"
    )


def _model_point():
    p = GliderParams(m=POINT["m"])
    x = tuple(POINT[f"{n}_0"] for n in ("V", "theta_g", "alpha", "omega2", "x", "z"))
    dist = (POINT["F_x"], POINT["F_z"], POINT["M_y"])
    return x, POINT["delta_0"], POINT["delta_cmd"], dist, p, POINT["tau_servo"], math.pi / 2


def test_the_fmu_declares_its_states_and_directional_derivatives(plant):
    md = read_model_description(str(plant))
    assert provides_directional_derivatives(plant)
    assert [u.variable.derivative.name for u in md.derivatives] == list(PLANT_STATES)
    assert [u.variable.name for u in md.derivatives] == [f"der({s})" for s in PLANT_STATES]
    # the dependencies declared are the FMU's own nonzero partial derivatives at POINT
    lin = linearize(plant, POINT)
    knowns = lin.states + lin.inputs
    for i, u in enumerate(md.derivatives):
        declared = {d.name for d in u.dependencies}
        nonzero = {knowns[j] for j in np.flatnonzero(np.hstack([lin.A[i], lin.B[i]]))}
        assert declared == nonzero, u.variable.name


def test_the_fmu_jacobian_is_the_models_bit_for_bit(plant):
    """A, B, C, D from fmi2/fmi3GetDirectionalDerivative equal the model's exact Jacobian
    (the C twin gives the same bits), and the state derivatives its values."""
    lin = linearize(plant, POINT)
    assert lin.states == PLANT_STATES and lin.inputs == PLANT_INPUTS
    J = np.array(plant_jacobian(*_model_point()))
    n = len(PLANT_STATES)
    assert np.array_equal(lin.A, J[:n, :n]) and np.array_equal(lin.B, J[:n, n:])
    assert np.array_equal(lin.derivatives, np.array(plant_derivatives(*_model_point())))
    # outputs: the states themselves, the pitch theta_g + alpha (theta and theta_meas)
    for i, name in enumerate(lin.outputs):
        want = J[n] if name in ("theta", "theta_meas") else np.eye(n + 4)[PLANT_STATES.index(name)]
        assert np.array_equal(np.concatenate([lin.C[i], lin.D[i]]), want), name
    assert not lin.D.any()  # no output depends on an input at the same instant


def test_the_fmu_jacobian_matches_central_differences_through_the_fmu(plant):
    """Each column against central differences of the FMU's own der(...) values, the
    state moved through its start value and the inputs set: 1e-6 relative."""
    lin = linearize(plant, POINT)
    J = np.hstack([lin.A, lin.B])
    knowns = [f"{s}_0" for s in PLANT_STATES] + list(PLANT_INPUTS)
    for j, name in enumerate(knowns):
        h = 1e-6 * max(1.0, abs(POINT.get(name, 0.0)))
        up = linearize(plant, {**POINT, name: POINT.get(name, 0.0) + h}).derivatives
        down = linearize(plant, {**POINT, name: POINT.get(name, 0.0) - h}).derivatives
        fd = (up - down) / (2 * h)
        err = np.abs(fd - J[:, j]) / np.maximum(1.0, np.abs(fd))
        assert err.max() < 1e-6, (name, fd, J[:, j])


def _initialised(fmu: Path, name: str) -> FMU2Slave:
    md = read_model_description(str(fmu))
    s = FMU2Slave(guid=md.guid, unzipDirectory=_extracted(fmu),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)  # fmt: skip
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    return s


@pytest.mark.parametrize("flavor", ["python", "native"])
def test_refused_where_it_does_not_apply(request, flavor, capfd):
    """Not of a parameter, not for a parameter, not on the observer: an fmi2Error with a
    message, never a crash or a silent zero (both flavors, the same messages)."""
    folder = request.getfixturevalue("fmu_dir" if flavor == "python" else "native_dir")
    md = read_model_description(str(folder / "GliderPlant.fmu"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = _initialised(folder / "GliderPlant.fmu", "p")
    assert s.getDirectionalDerivative([vr["der(V)"]], [vr["M_y"]], [1.0]) == [0.0]
    assert s.getDirectionalDerivative([vr["theta"]], [vr["alpha"]], [2.0]) == [2.0]
    capfd.readouterr()
    cases = (([vr["der(V)"]], [vr["m"]], f"value reference {vr['m']} (m) is not a known: "
              "expected a continuous state or an input"),
             ([vr["m"]], [vr["V"]], f"value reference {vr['m']} (m) is not an unknown: expected "
              "an output or a state derivative"),
             ([vr["der(V)"]], [10_000], "value reference 10000 does not exist"))  # fmt: skip
    for unknowns, knowns, message in cases:
        s.reset()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        with pytest.raises(FMICallException):
            s.getDirectionalDerivative(unknowns, knowns, [1.0])
        assert message in capfd.readouterr().out
    s.reset()
    s.freeInstance()
    o = _initialised(folder / "GliderObserver.fmu", "o")
    with pytest.raises(FMICallException):
        o.getDirectionalDerivative([0], [0], [1.0])
    assert "fmi2GetDirectionalDerivative: not supported by this FMU" in capfd.readouterr().out
    o.freeInstance()
    with pytest.raises(LinearizationError):
        linearize(folder / "GliderObserver.fmu")


def test_analyze_from_the_fmu_matches_todays_eigenvalues(fmu_dir, native_dir):
    """Every closed-loop and the open-loop Jacobian's eigenvalues from the FMU equal those
    of the model's central differences to 1e-9 (both flavors, every K_Fdelta studied)."""
    from glider_cosim.studies.analysis import fmu_plant_jacobian

    for folder in (fmu_dir, native_dir):
        jac = fmu_plant_jacobian(folder / "GliderPlant.fmu")
        for kf in (15.0, 29.5, 45.0):
            p = GliderParams(K_Fdelta=kf)
            assert jac.residual(p) < 1e-15
            for k in (None, *K_C_LIST):
                old = np.sort_complex(np.linalg.eigvals(closed_loop_matrix(p, k)))
                new = np.sort_complex(np.linalg.eigvals(closed_loop_matrix(p, k, jac)))
                assert np.max(np.abs(new - old)) < 1e-9, (kf, k)


def test_analyze_from_fmu_report(fmu_dir):
    """The whole report from the FMU equals the model's but for the lines it adds (the
    stable-K_c edges agree to the digits shown)."""
    a = analyze(plant_fmu=fmu_dir / "GliderPlant.fmu")
    b = analyze()
    assert a.pop("linearization")["residual"] < 1e-15
    assert a["stable_K_c"]["continuous"][0] == pytest.approx(b["stable_K_c"]["continuous"][0],
                                                             rel=1e-6)  # fmt: skip
    for ca, cb in zip(a["closed_loop"], b["closed_loop"], strict=True):
        np.testing.assert_allclose(ca["continuous_eigenvalues"], cb["continuous_eigenvalues"],
                                   atol=1e-9)  # fmt: skip
        assert ca["sampled_spectral_radius"] == cb["sampled_spectral_radius"]


def test_cli_from_fmu_and_its_errors(fmu_dir, capsys):
    from glider_cosim.cli import main

    assert main(["analyze", "--from-fmu", "--fmu-dir", str(fmu_dir), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["linearization"]["plant_fmu"] == str(fmu_dir / "GliderPlant.fmu")
    assert result["equilibrium"]["V"] == equilibrium(GliderParams()).V
    assert main(["analyze", "--flavor", "native"]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "glider-cosim analyze: error: --flavor needs --from-fmu (the model's own Jacobian "
        "uses no FMU)"
    )


def test_the_docs_fmpy_snippet_linearizes_the_plant(fmu_dir, capsys):
    """docs/how-to/linearize.md's snippet, run as written on our plant: A and B equal the
    model's Jacobian at the FMU's start values."""
    page = (Path(__file__).resolve().parents[2] / "docs" / "how-to" / "linearize.md").read_text()
    code = page[page.index("```python\n") + 10 : page.index("\n```", page.index("```python"))]
    assert 'fmu = "GliderPlant.fmu"\n' in code
    ns: dict = {}
    exec(code.replace('"GliderPlant.fmu"', repr(str(fmu_dir / "GliderPlant.fmu"))), ns)
    J = np.array(plant_jacobian(*_start_point()))
    assert np.array_equal(ns["A"], J[:7, :7]) and np.array_equal(ns["B"], J[:7, 7:])
    assert capsys.readouterr().out.count("j") == 4  # four complex-typed eigenvalues printed


def _start_point() -> tuple:
    """plant_jacobian's arguments at the plant FMU's start values (the slave's defaults)."""
    from glider_plant.slave import GliderPlant

    start = {v.name: v.start for v in GliderPlant.VARIABLES}
    x = tuple(start[f"{n}_0"] for n in ("V", "theta_g", "alpha", "omega2", "x", "z"))
    return (x, start["delta_0"], start["delta_cmd"], (start["F_x"], start["F_z"], start["M_y"]),
            GliderParams(), start["tau_servo"], start["delta_max"])  # fmt: skip


def test_fmi3_refuses_time_as_a_known(fmi3_dirs, capfd):
    """FMI 3's independent variable is declared (value reference after the model's) but is
    neither a known nor an unknown of the step mode's derivatives."""
    from fmpy.fmi3 import FMU3Slave

    for flavor in ("python", "native"):
        fmu = fmi3_dirs[flavor] / "GliderPlant.fmu"
        md = read_model_description(str(fmu))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        mid = md.coSimulation.modelIdentifier
        s = FMU3Slave(guid=md.guid, unzipDirectory=_extracted(fmu), modelIdentifier=mid)
        s.instantiate()
        s.enterInitializationMode(startTime=0.0)
        s.exitInitializationMode()
        assert s.getDirectionalDerivative([vr["der(z)"]], [vr["V"]], [1.0]) != [0.0]
        capfd.readouterr()
        with pytest.raises(FMICallException):
            s.getDirectionalDerivative([vr["der(V)"]], [vr["time"]], [1.0])
        assert (
            f"fmi3GetDirectionalDerivative: value reference {vr['time']} (time) is not a "
            "known: expected a continuous state or an input"
        ) in capfd.readouterr().out
        s.freeInstance()
