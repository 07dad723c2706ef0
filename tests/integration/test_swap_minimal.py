"""Swapping in a foreign plant FMU that has only the essential variables.

The plant is written here, in another style than ours and than SwapTestPlant: a state
tuple, classic RK4 at fixed 4 ms sub-steps, no servo, no sensor noise, no disturbance
inputs, no parameters (the paper's Sec. 3.3 start is built in), and only ``delta_cmd``
in and ``theta_meas``, ``V``, ``theta_g`` out. The loop needs only the connections that
carry it: the disturbance inputs the scenario does not use and the recorded outputs the
FMU lacks are skipped with a note; a missing required connection is named.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import pytest

from glider_cosim.cli import main
from glider_cosim.master import SystemSpecError
from glider_cosim.runner import simulate
from glider_cosim.scenarios.scenario import parse_scenario
from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

pytestmark = pytest.mark.integration
THETA_GE = equilibrium(GliderParams()).theta_g

SOURCE = """
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Real

# paper Sec. 3.3: m, J2, K_L0, K_L, K_D0, K_D, K_q, K_M0, K_M, K_Fdelta, m0, g
C = (10.0, 0.08, 0.0, 303.6, 3.15, 282.8, -0.8, 0.39, -14.7, 29.5, 0.05, 9.81)
SUB = 0.004


def rates(x, u):
    m, J2, KL0, KL, KD0, KD, Kq, KM0, KM, KFd, m0, g = C
    V, tg, a, w = x
    q = V * V
    lift, drag = (KL0 + KL * a) * q, (KD0 + KD * a * a) * q
    f_tail = KFd * q * u
    moment = (KM0 + KM * a + Kq * w) * q - KM * u * q
    dV = (-m0 * g * math.sin(tg) - drag + f_tail * math.sin(a)) / m
    dtg = (-m0 * g * math.cos(tg) + lift + f_tail * math.cos(a)) / (m * V)
    return (dV, dtg, w - dtg, moment / J2)


def rk4(x, u, h):
    k1 = rates(x, u)
    k2 = rates(tuple(xi + h / 2 * ki for xi, ki in zip(x, k1)), u)
    k3 = rates(tuple(xi + h / 2 * ki for xi, ki in zip(x, k2)), u)
    k4 = rates(tuple(xi + h * ki for xi, ki in zip(x, k3)), u)
    return tuple(xi + h / 6 * (a + 2 * b + 2 * c + d)
                 for xi, a, b, c, d in zip(x, k1, k2, k3, k4))


class NAME(Fmi2Slave):
    description = "minimal glider plant"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = (0.2, math.radians(-35.0), math.radians(1.0), 0.0)
        self.delta_cmd = 0.0
        self.register_variable(Real("delta_cmd", causality=Fmi2Causality.input))
        outputs = {"theta_meas": lambda: self.x[1] + self.x[2], "V": lambda: self.x[0],
                   "theta_g": lambda: self.x[1]}
        for name in OUTPUTS:
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        getter=outputs[name]))

    def to_xml(self, model_options=None):
        root = super().to_xml(model_options or {})
        for unknown in root.find("ModelStructure").find("Outputs"):
            unknown.set("dependencies", "")  # states: no direct feedthrough
        return root

    def do_step(self, current_time, step_size):
        n = max(1, round(step_size / SUB))
        for _ in range(n):
            self.x = rk4(self.x, self.delta_cmd, step_size / n)
        return self.x[0] > 1e-3
"""


@pytest.fixture(scope="module")
def minimal(tmp_path_factory) -> dict[str, Path]:
    """The minimal plant, and a variant without theta_meas (on our FMI runtime where the
    project has one, else on pythonfmu's binary)."""
    from pythonfmu.builder import FmuBuilder

    try:
        from glider_cosim.fmus.python import build_slave_fmu
    except ImportError:
        build_slave_fmu = None
    out = tmp_path_factory.mktemp("minimal_fmus")
    fmus = {}
    for name, outputs in (("MinimalPlant", ("theta_meas", "V", "theta_g")),
                          ("MinimalPlantNoMeas", ("V", "theta_g"))):  # fmt: skip
        src = out / f"{name}.py"
        text = SOURCE.replace("class NAME", f"class {name}").replace("OUTPUTS", repr(outputs))
        src.write_text(text)
        if build_slave_fmu is not None:
            fmus[name] = Path(build_slave_fmu(src, out / "built"))
        else:
            fmus[name] = Path(FmuBuilder.build_FMU(src, dest=out / "built"))
    return fmus


def test_the_minimal_plant_swaps_in_with_notes(minimal, fmu_dir, caplog):
    sc = parse_scenario({"name": "minimal", "stop_time": 30.0,
                         "fmus": {"plant": str(minimal["MinimalPlant"])}})  # fmt: skip
    with caplog.at_level(logging.WARNING, logger="glider_cosim"):
        r = simulate(sc, None, fmu_dir=fmu_dir, build=False)
    assert r.status == "ok", r.message
    notes = [rec.getMessage() for rec in caplog.records if rec.name == "glider_cosim.runner.run"]
    for name in ("F_x", "F_z", "M_y"):
        assert any(f"has no input {name}: skipped" in n for n in notes), notes
    assert {"plant.theta_meas", "plant.V", "plant.theta_g"} <= set(r.columns)
    assert "plant.z" not in r.columns
    theta_g = r.column("plant.theta_g")
    # our observer and passivity law (K_c = 10) settle the foreign plant at the paper's glide
    assert abs(theta_g[-1] - THETA_GE) < math.radians(0.1), math.degrees(theta_g[-1])
    assert abs(theta_g[0] - math.radians(-35.0)) < 1e-12
    assert r.metrics["settling_time_s"] is not None and r.metrics["settling_time_s"] < 20.0


def test_recorded_outputs_the_swapped_plant_lacks_are_skipped(minimal, fmu_dir, caplog):
    sc = parse_scenario({"stop_time": 1.0, "record": ["plant.theta_g", "plant.z"],
                         "fmus": {"plant": str(minimal["MinimalPlant"])}})  # fmt: skip
    with caplog.at_level(logging.WARNING, logger="glider_cosim"):
        r = simulate(sc, None, fmu_dir=fmu_dir, build=False)
    assert r.columns == ["time", "plant.theta_g"]
    assert any("has no variable 'z': not recorded" in rec.getMessage() for rec in caplog.records)


def test_a_disturbance_makes_its_input_required(minimal, fmu_dir):
    sc = parse_scenario(
        {
            "stop_time": 1.0,
            "fmus": {"plant": str(minimal["MinimalPlant"])},
            "disturbance": [{"target": "plant.F_z", "time": 0.5, "value": 0.1}],
        }
    )
    with pytest.raises(SystemSpecError, match=r"driven input plant.F_z: instance plant "
                       r"\(MinimalPlant\) has no variable 'F_z'"):  # fmt: skip
        simulate(sc, None, fmu_dir=fmu_dir, build=False)


def test_a_missing_required_connection_is_named(minimal, fmu_dir, capsys, tmp_path):
    sc = tmp_path / "s.toml"
    sc.write_text(f"[fmus]\nplant = '{minimal['MinimalPlantNoMeas']}'\n")
    code = main(["run", str(sc), "--fmu-dir", str(fmu_dir), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert (
        "connection plant.theta_meas -> observer.theta_meas: instance plant "
        "(MinimalPlantNoMeas) has no variable 'theta_meas'"
    ) in err
    assert len(err.strip().splitlines()) == 1


def test_cli_prints_the_notes_on_stderr(minimal, fmu_dir, capsys, tmp_path):
    sc = tmp_path / "s.toml"
    sc.write_text(f"stop_time = 2.0\n[fmus]\nplant = '{minimal['MinimalPlant']}'\n")
    code = main(["run", str(sc), "--fmu-dir", str(fmu_dir), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 0, err
    notes = [line for line in err.splitlines() if line.startswith("glider-cosim: note: ")]
    assert len(notes) == 3 and all("skipped" in n for n in notes), err
    assert sorted(p.name for p in (tmp_path / "o").glob("*.png")) == [
        "glide_angle.png",
        "pitch.png",
        "speed.png",
        "tail_angle.png",
    ]
