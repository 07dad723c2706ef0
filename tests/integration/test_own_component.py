"""Issue 54 items 1-2: a controller or estimator with the interface the README states runs
in the loop; its optional and extra inputs are wired by name with one note; a one-step-late
output is named by ``run`` with the fix (pythonfmu FMUs built here, in ``tmp_path``)."""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import pytest

from glider_cosim.master import SystemSpecError
from glider_cosim.runner import simulate
from glider_cosim.runner.probe import LATE_FIX, probe_feedthrough
from glider_cosim.scenarios.scenario import parse_scenario
from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

pytestmark = pytest.mark.integration
THETA_GE = equilibrium(GliderParams()).theta_g

HEAD = """
from pythonfmu import Fmi2Causality, Fmi2Slave, Real

IN, OUT = Fmi2Causality.input, Fmi2Causality.output
"""

SOURCES = {
    # the README's interface alone: theta_g_hat in, delta_cmd out, computed when read
    "PController": """
class PController(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.theta_g_hat = -0.39
        self.register_variable(Real("theta_g_hat", causality=IN))
        self.register_variable(Real("delta_cmd", causality=OUT, getter=self.law))

    def law(self):
        return max(-0.5, min(0.5, -0.5 * (self.theta_g_hat - THETA_GE)))

    def do_step(self, t, dt):
        return True
""",
    # extra inputs: theta_meas (the plant has that output) and gain_scale (nobody has)
    "ExtraController": """
class ExtraController(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.theta_g_hat, self.theta_meas, self.gain_scale = -0.39, -0.37, 1.0
        for name in ("theta_g_hat", "theta_meas", "gain_scale"):
            self.register_variable(Real(name, causality=IN))
        self.register_variable(Real("delta_cmd", causality=OUT, getter=self.law))

    def law(self):
        return max(-0.5, min(0.5, -0.5 * self.gain_scale * (self.theta_g_hat - THETA_GE)))

    def do_step(self, t, dt):
        return True
""",
    # the usual pythonfmu pattern: the output set in do_step, one step late
    "LateController": """
class LateController(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.theta_g_hat, self.delta_cmd = -0.39, 0.0
        self.register_variable(Real("theta_g_hat", causality=IN))
        self.register_variable(Real("delta_cmd", causality=OUT))

    def do_step(self, t, dt):
        self.delta_cmd = max(-0.5, min(0.5, -0.5 * (self.theta_g_hat - THETA_GE)))
        return True
""",
    # no delta_cmd output: refused, with what is required named
    "MuteController": """
class MuteController(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.theta_g_hat, self.u = 0.0, 0.0
        self.register_variable(Real("theta_g_hat", causality=IN))
        self.register_variable(Real("u", causality=OUT))

    def do_step(self, t, dt):
        return True
""",
    # an estimator with the required interface alone: theta_meas in, theta_g_hat out
    "LagEstimator": """
class LagEstimator(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.theta_meas, self.theta_g_hat = -0.37, -0.61
        self.register_variable(Real("theta_meas", causality=IN))
        self.register_variable(Real("theta_g_hat", causality=OUT))

    def do_step(self, t, dt):
        alpha = 0.0265  # the steady glide's angle of attack (rad)
        self.theta_g_hat += dt / 0.3 * (self.theta_meas - alpha - self.theta_g_hat)
        return True
""",
}


@pytest.fixture(scope="module")
def own(tmp_path_factory) -> dict[str, Path]:
    """The FMUs of :data:`SOURCES`, built with pythonfmu on our runtime."""
    from glider_cosim.fmus.python import build_slave_fmu

    out = tmp_path_factory.mktemp("own_fmus")
    fmus = {}
    for name, body in SOURCES.items():
        src = out / f"{name}.py"
        src.write_text(HEAD + f"THETA_GE = {THETA_GE!r}\n" + body)
        fmus[name] = Path(build_slave_fmu(src, out / "built"))
    return fmus


def _run(fmus: dict[str, Path], caplog, stop: float = 40.0, **extra):
    sc = parse_scenario({"stop_time": stop, "fmus": {k: str(v) for k, v in fmus.items()},
                         **extra})  # fmt: skip
    with caplog.at_level(logging.WARNING, logger="glider_cosim"):
        r = simulate(sc, None, fmu_dir=None)
    notes = [rec.getMessage() for rec in caplog.records if rec.name == "glider_cosim.runner.run"]
    return r, notes


def test_the_readme_interface_alone_runs_and_names_what_is_unconnected(own, caplog):
    r, notes = _run({"controller": own["PController"]}, caplog)
    assert r.status == "ok", r.message
    assert notes == [
        "controller ('PController'): not connected: observer.V_hat (no optional input V_hat)"
    ]
    assert abs(r.column("plant.theta_g")[-1] - THETA_GE) < math.radians(0.2)


def test_extra_inputs_are_connected_by_name_or_left_at_their_start(own, caplog):
    r, notes = _run(
        {"controller": own["ExtraController"]}, caplog, stop=2.0,
        record=["plant.theta_meas", "controller.theta_meas", "controller.gain_scale"],
    )  # fmt: skip
    assert r.status == "ok", r.message
    assert notes == [
        "controller ('ExtraController'): not connected: observer.V_hat (no optional input "
        "V_hat); input gain_scale, left at its start value (no output gain_scale in the loop); "
        "connected by name: plant.theta_meas -> controller.theta_meas"
    ]
    assert list(r.column("controller.theta_meas")) == list(r.column("plant.theta_meas"))
    assert set(r.column("controller.gain_scale")) == {1.0}


def test_a_controller_without_delta_cmd_is_refused_in_one_line(own, caplog):
    with pytest.raises(SystemSpecError, match=r"controller \('MuteController'\) lacks what the "
                       r"loop requires of the controller: delta_cmd \(output, rad\)"):  # fmt: skip
        _run({"controller": own["MuteController"]}, caplog, stop=1.0)


def test_an_estimator_with_the_required_interface_runs_with_a_controller_that_needs_no_v(
    own, caplog
):
    r, notes = _run({"observer": own["LagEstimator"], "controller": own["PController"]}, caplog)
    assert r.status == "ok", r.message
    assert sorted(notes) == [
        "controller ('PController'): not connected: observer.V_hat (no optional input V_hat)",
        "observer ('LagEstimator'): not connected: controller.delta_cmd (no optional input "
        "delta_cmd)",
    ]
    assert abs(r.column("plant.theta_g")[-1] - THETA_GE) < math.radians(0.5)


def test_our_controller_needs_v_hat_of_the_estimator(own, caplog):
    with pytest.raises(SystemSpecError, match=r"observer \('LagEstimator'\) has no output V_hat "
                       r"\(m/s\), which controller \('GliderController'\) reads as "
                       r"controller.V_hat"):  # fmt: skip
        _run({"observer": own["LagEstimator"]}, caplog, stop=1.0)


def test_the_probe_tells_a_late_output_from_a_direct_one(own, fmu_dir):
    assert probe_feedthrough(own["LateController"]).kind == "late"
    assert probe_feedthrough(own["PController"]).kind == "direct"
    assert probe_feedthrough(fmu_dir / "GliderController.fmu").kind == "direct"


def test_run_names_a_one_step_late_controller_with_the_fix(own, caplog):
    r, notes = _run({"controller": own["LateController"]}, caplog, stop=1.0)
    assert r.status == "ok"
    late = [n for n in notes if "late" in n]
    assert late == [
        "controller (LateController.fmu): delta_cmd responds to theta_g_hat one step "
        f"(0.02 s) late: {LATE_FIX}"
    ]
    caplog.clear()
    _, notes = _run({"controller": own["PController"]}, caplog, stop=1.0)
    assert not [n for n in notes if "late" in n]


def test_verify_judges_a_new_law_on_what_the_loop_needs(own, capsys):
    from glider_cosim.cli import main
    from glider_cosim.verify import verify

    report = verify(own["PController"])
    assert [(c.name, c.passed) for c in report.loop] == [
        ("interface", True), ("initialization", True), ("feedthrough", True),
        ("closed loop", True),
    ]  # fmt: skip
    assert report.passed and not report.port and report.results == []
    assert main(["verify", str(own["PController"])]) == 0
    out = capsys.readouterr().out
    assert "apply only to ports of our laws" in out
    assert out.rstrip().endswith(
        "controller (PController): loop checks 4 of 4 pass, reference "
        "cases not counted (not a port): PASS"
    )
    assert main(["verify", str(own["PController"]), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["port"] is False and data["exit_code"] == 0
    assert [c["result"] for c in data["loop_checks"]] == ["pass"] * 4


def test_verify_names_a_late_output_with_the_fix(own, capsys):
    from glider_cosim.cli import main

    assert main(["verify", str(own["LateController"])]) == 1
    row = next(line for line in capsys.readouterr().out.splitlines()
               if line.startswith("feedthrough"))  # fmt: skip
    assert row.split()[1] == "FAIL" and row.endswith(LATE_FIX)


def test_verify_an_estimator_and_what_our_controller_reads(own, capsys):
    from glider_cosim.cli import main
    from glider_cosim.verify import verify

    report = verify(own["LagEstimator"])
    assert report.component == "observer"
    checks = {c.name: c for c in report.loop}
    assert list(checks) == ["interface", "initialization", "closed loop"]
    assert checks["interface"].passed and checks["initialization"].passed
    assert not checks["closed loop"].passed
    assert "has no output V_hat (m/s), which controller ('GliderController') reads" in (
        checks["closed loop"].detail
    )
    assert main(["verify", str(own["MuteController"]), "--component", "controller"]) == 2
    err = capsys.readouterr().err
    assert "lacks what the loop requires of the controller: delta_cmd (output, rad)" in err


def test_compare_runs_the_benchmark_set_and_says_where_theirs_is_better(own, tmp_path, capsys):
    import csv
    import hashlib

    from glider_cosim.cli import main
    from glider_cosim.studies.compare import GRID_DEG

    fmu = own["PController"]
    before = hashlib.sha256(fmu.read_bytes()).hexdigest()
    sc = tmp_path / "mine.toml"
    sc.write_text(f"name = 'mine'\n[fmus]\ncontroller = '{fmu}'\n")
    out = tmp_path / "cmp"
    assert main(["compare", str(sc), "--out", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    names = ["default", "noisy-pitch", "depth-protocol"] + [f"start{d:+.0f}deg" for d in GRID_DEG]
    assert [line.split(" ")[0] for line in printed[:-1]] == names
    assert all(": theirs is better in " in line for line in printed[:-1])
    assert sorted(p.name for p in out.glob("*.png")) == sorted(f"compare-{n}.png" for n in names)
    with (out / "compare.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 6 * len(names)
    assert {r["theirs_is"] for r in rows} <= {"better", "worse", "same"}
    assert {r["measure"] for r in rows} == {"settling", "rise", "overshoot", "effort",
                                            "largest tail angle", "outcome"}  # fmt: skip
    default = {r["measure"]: r for r in rows if r["case"] == "default"}
    assert default["outcome"]["ours"] == "settled"  # our passivity law, K_c = 10
    assert float(default["settling"]["ours"]) > 0
    md = (out / "compare.md").read_text()
    assert "## Where theirs beats ours, and where not" in md and "(better)" in md
    page = (out / "compare.html").read_text()
    assert page.count("<img ") == len(names) and 'class="better"' in page
    assert hashlib.sha256(fmu.read_bytes()).hexdigest() == before  # never written into


def test_compare_refuses_a_scenario_without_a_component_in_one_line(own, tmp_path, capsys):
    from glider_cosim.cli import main

    sc = tmp_path / "plain.toml"
    sc.write_text("name = 'plain'\n")
    assert main(["compare", str(sc), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"glider-cosim compare: error: {sc}: [fmus] swaps nothing: expected exactly "
                   "one of controller or observer (compare puts your component in our loop, "
                   "beside ours)"]  # fmt: skip
    assert not (tmp_path / "o").exists()
