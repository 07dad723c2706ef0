"""Each FMU alone under fmpy: validation, state save/restore, feedthrough, accuracy,
reference CSVs, parameter refusal."""

from __future__ import annotations

import math
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu
from scipy.integrate import solve_ivp

from glider_controller.laws import passivity_law
from glider_cosim.fmus.python import COMPONENTS
from glider_cosim.master import CoSimulation, FMUCallError, System
from glider_cosim.master.instance import _extracted
from glider_cosim.runner.recorders import ArrayRecorder
from glider_cosim.verify.reference import ATOL, CASES, read_csv, run_reference
from glider_plant.model import derivatives, equilibrium
from glider_plant.params import GliderParams

pytestmark = pytest.mark.integration
NAMES = [c.name for c in COMPONENTS]


class Slave:
    """Minimal direct fmpy driver with name-based access (value references looked up)."""

    def __init__(self, fmu: Path, name: str = "inst"):
        self.md = read_model_description(str(fmu))
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.dir = _extracted(Path(fmu))  # shared, never unloaded (see the master)
        self.s = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=self.dir,
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.s.instantiate()
        self.t = 0.0

    def set(self, **values):
        for k, v in values.items():
            var = self.vars[k]
            if var.type == "Real":
                self.s.setReal([var.valueReference], [float(v)])
            elif var.type == "Integer":
                self.s.setInteger([var.valueReference], [int(v)])
            else:
                self.s.setBoolean([var.valueReference], [bool(v)])

    def get(self, *names):
        return self.s.getReal([self.vars[n].valueReference for n in names])

    def init(self, **params):
        self.s.setupExperiment(startTime=0.0)
        self.set(**params)
        self.s.enterInitializationMode()
        self.s.exitInitializationMode()

    def step(self, h):
        self.s.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
        self.t += h

    def outputs(self):
        return [v.name for v in self.md.modelVariables if v.causality == "output"]

    def free(self):
        self.s.terminate()
        self.s.fmi2FreeInstance(self.s.component)


@pytest.mark.parametrize("name", NAMES)
def test_fmu_passes_fmpy_validation(flavor_dir, name):
    assert validate_fmu(str(flavor_dir / f"{name}.fmu")) == []


@pytest.mark.parametrize("name", NAMES)
def test_model_description_has_units_structure_and_state_flag(flavor_dir, name):
    md = read_model_description(str(flavor_dir / f"{name}.fmu"))
    assert md.coSimulation.canGetAndSetFMUstate
    assert {u.name for u in md.unitDefinitions} >= {"rad"}
    rad = next(u for u in md.unitDefinitions if u.name == "rad")
    assert [d.name for d in rad.displayUnits] == ["deg"]
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    # the initial unknowns: the outputs and the state derivatives (the plant's: FMI 2.0)
    derivatives = [u.variable for u in md.derivatives]
    assert [u.variable for u in md.initialUnknowns] == outputs + derivatives and outputs
    assert len(derivatives) == (7 if name == "GliderPlant" else 0)
    for v in md.modelVariables:
        if v.type in ("Integer", "Boolean"):
            assert v.variability != "continuous"
        if v.type == "Real" and v.causality in ("input", "output"):
            assert v.unit, v.name


def test_shared_modules_are_identical_and_scripts_unique(fmu_dir):
    files: dict[str, dict[str, bytes]] = {}
    for name in NAMES:
        with zipfile.ZipFile(fmu_dir / f"{name}.fmu") as z:
            files[name] = {
                n: z.read(n)
                for n in z.namelist()
                if n.startswith("resources/") and n.endswith(".py")
            }
    scripts = [f"resources/{n}.py" for n in NAMES]
    for name in NAMES:
        own = f"resources/{name}.py"
        assert own in files[name]
        assert not any(s in files[name] for s in scripts if s != own)
    for a in NAMES:
        for b in NAMES:
            for path in set(files[a]) & set(files[b]):
                assert files[a][path] == files[b][path], f"{path} differs in {a} and {b}"


STATE_CASES = {
    "GliderPlant": ({"noise_std": 0.02, "noise_seed": 5}, {"delta_cmd": 0.3, "F_z": 0.1}),
    "GliderObserver": ({}, {"theta_meas": -0.30, "delta_cmd": 0.05}),
    "GliderController": ({"law": 3, "K_I": 2.0}, {"V_hat": 0.21, "theta_g_hat": -0.5}),
}


@pytest.mark.parametrize("name", NAMES)
def test_get_set_fmu_state_restores_internal_state(flavor_dir, name):
    params, inputs = STATE_CASES[name]
    s = Slave(flavor_dir / f"{name}.fmu")
    s.init(**params)
    outs = s.outputs()
    s.set(**inputs)
    for _ in range(7):
        s.step(0.02)
    state = s.s.getFMUstate()
    t_saved = s.t
    first = []
    for k in range(25):
        s.set(**{n: v * (1 + 0.01 * k) for n, v in inputs.items()})
        s.step(0.02)
        first.append(s.get(*outs))
    s.s.setFMUstate(state)
    s.t = t_saved
    second = []
    for k in range(25):
        s.set(**{n: v * (1 + 0.01 * k) for n, v in inputs.items()})
        s.step(0.02)
        second.append(s.get(*outs))
    s.s.freeFMUstate(state)
    s.free()
    assert first == second
    assert first[0] != first[-1]  # the run really moved on


def test_controller_has_direct_feedthrough(flavor_dir):
    s = Slave(flavor_dir / "GliderController.fmu")
    s.init(law=1, K_c=4.0)
    p = GliderParams()
    e = equilibrium(p)
    for V, th in [(0.2, -0.6), (0.25, -0.3), (e.V, e.theta_g)]:
        s.set(V_hat=V, theta_g_hat=th)  # no doStep in between
        assert s.get("delta_cmd")[0] == pytest.approx(
            passivity_law(V, th, 4.0, p, e, math.pi / 2), abs=1e-15
        )
    md = s.md
    dep = {u.variable.name: [d.name for d in u.dependencies] for u in md.outputs}
    assert dep == {"delta_cmd": ["V_hat", "theta_g_hat"]}
    s.free()


@pytest.mark.parametrize("h", [0.02, 0.05, 0.1])
def test_plant_fmu_matches_solve_ivp(fmu_dir, h):
    """Sec. 3.3 initial state, tail held at zero, 60 s: glide angle within 1e-6 rad."""
    p = GliderParams()
    x0 = [0.2, math.radians(-35.0), math.radians(1.0), 0.0]
    ref = solve_ivp(
        lambda t, x: derivatives(t, tuple(x), 0.0, p),
        (0, 60),
        x0,
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        dense_output=True,
    )
    s = Slave(fmu_dir / "GliderPlant.fmu")
    s.init()
    n = round(60.0 / h)
    worst = 0.0
    for k in range(n):
        s.step(h)
        worst = max(worst, abs(s.get("theta_g")[0] - ref.sol((k + 1) * h)[1]))
    s.free()
    assert worst < 1e-6


@pytest.mark.parametrize("name", NAMES)
def test_reference_csv(fmu_dir, name):
    folder = CASES[name]["folder"]
    inputs = read_csv(folder / "reference_input.csv")
    cols, data = run_reference(name, fmu_dir / f"{name}.fmu", inputs)
    ref_cols, ref = read_csv(folder / "reference_output.csv")
    assert cols == ref_cols
    assert data.shape == ref.shape
    np.testing.assert_allclose(data, ref, rtol=0, atol=ATOL)


@pytest.mark.parametrize(
    ("name", "params", "message"),
    [
        ("GliderPlant", {"m": -1.0}, "m = -1.0 is invalid: expected a finite value in (0, inf)"),
        ("GliderPlant", {"J2": 0.0}, "J2 = 0.0 is invalid"),
        ("GliderPlant", {"tau_servo": 0.0}, "tau_servo = 0.0 is invalid"),
        ("GliderPlant", {"V_0": -0.1}, "V_0 = -0.1 is invalid"),
        ("GliderPlant", {"K_L": float("nan")}, "K_L = nan is invalid"),
        ("GliderObserver", {"f_cutoff": 25.0}, "f_cutoff = 25.0 is invalid: expected a value in"),
        ("GliderObserver", {"m0": float("inf")}, "m0 = inf is invalid"),
        ("GliderController", {"K_c": -2.0}, "K_c = -2.0 is invalid"),
        ("GliderController", {"law": 7}, "law = 7 is invalid: expected an integer in [0, 3]"),
    ],
)
def test_invalid_parameters_are_refused_before_the_first_step(fmu_dir, name, params, message):
    fmu = fmu_dir / f"{name}.fmu"
    inputs = [
        v.name for v in read_model_description(str(fmu)).modelVariables if v.causality == "input"
    ]
    system = System(
        fmus={"x": fmu},
        connections=[],
        parameters={"x": params},
        driven={f"x.{i}": 0.1 for i in inputs},
    )
    sim = CoSimulation(system)
    with pytest.raises(FMUCallError) as err:
        sim.run(1.0, ArrayRecorder())
    sim.close()
    assert err.value.call == "fmi2ExitInitializationMode"
    assert err.value.status == 3  # fmi2Error (not fatal): never a run producing NaNs
    assert message in str(err.value)
    assert "\n" not in str(err.value)


def test_interface_docs_are_generated_from_the_fmus(fmu_dir):
    from glider_cosim.fmus.docs import interface_markdown

    text = interface_markdown({n: fmu_dir / f"{n}.fmu" for n in NAMES})
    doc = Path(__file__).resolve().parents[2] / "docs" / "reference" / "fmu-interfaces.md"
    assert doc.read_text() == text, "run: python -m glider_cosim.fmus.docs"
