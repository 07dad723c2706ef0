"""The component verification kit on FMUs: our own (every flavor), broken ones, the CLI,
the drift of the shipped references and the cross-check export."""

from __future__ import annotations

import hashlib
import json
import shutil
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest

import glider_controller
import glider_fmi
import glider_plant
from glider_cosim.cli import main
from glider_cosim.runner.provenance import file_sha256
from glider_cosim.testing import assert_matches_reference
from glider_cosim.verify import (
    COMPONENTS,
    RUNNERS,
    VerifyInputError,
    case_names,
    export,
    kit_files,
    kit_root,
    load_case,
    verify,
    write_references,
)
from glider_cosim.verify.cases import DEFAULT_CASE
from glider_cosim.verify.compare import ONE_STEP_LATE
from glider_cosim.verify.run import open_fmu

pytestmark = pytest.mark.integration

#: the flavors of our three FMUs; each needs a fixture ``<flavor>_fmus`` returning a folder
#: holding GliderPlant.fmu, GliderObserver.fmu and GliderController.fmu
FMU_SETS = ["python", "native", "fmi3_python", "fmi3_native"]
ALL = [(c, n) for c in COMPONENTS for n in case_names(c)]


@pytest.fixture(scope="session")
def python_fmus(fmu_dir) -> Path:
    """Our FMUs authored with pythonfmu (the session build)."""
    return fmu_dir


@pytest.fixture(scope="session")
def native_fmus(native_dir) -> Path:
    """Our FMUs in the native flavor (C99 behind the same FMI layer)."""
    return native_dir


@pytest.fixture(scope="session")
def fmi3_python_fmus(fmi3_dirs) -> Path:
    """Our Python-flavor FMUs as FMI 3.0."""
    return fmi3_dirs["python"]


@pytest.fixture(scope="session")
def fmi3_native_fmus(fmi3_dirs) -> Path:
    """Our native FMUs as FMI 3.0."""
    return fmi3_dirs["native"]


@pytest.fixture(scope="session", params=FMU_SETS)
def fmu_set(request) -> Path:
    """A folder of our three FMUs, of each flavor in :data:`FMU_SETS`."""
    return request.getfixturevalue(f"{request.param}_fmus")


@pytest.mark.parametrize(("component", "name"), ALL)
def test_our_fmus_match_every_reference(fmu_set, component, name):
    assert_matches_reference(fmu_set / f"{COMPONENTS[component]}.fmu", component, name)


def test_the_shipped_references_do_not_drift(fmu_dir, tmp_path):
    """A fresh run of the reference models writes the shipped references exactly
    (tolerance 0: same code, same numbers; every value written in its exact form)."""
    write_references(fmu_dir, tmp_path)
    for shipped in kit_files():
        fresh = tmp_path / shipped.parent.name / shipped.name
        assert fresh.read_bytes() == shipped.read_bytes(), shipped.name


BROKEN = {
    "BrokenServoPlant": (
        (glider_plant, glider_fmi),
        '''
from glider_plant.model import saturate
from glider_plant.slave import GliderPlant


class BrokenServoPlant(GliderPlant):
    """GliderPlant with the servo bypassed: the tail jumps to the command."""

    def step(self, t, h):
        self.delta = saturate(self.delta_cmd, self.delta_max)
        return super().step(t, h)
''',
    ),
    "FlippedController": (
        (glider_controller, glider_plant, glider_fmi),
        '''
from glider_controller.slave import GliderController


class FlippedController(GliderController):
    """GliderController with the sign of its feedback flipped (open loop untouched)."""

    def command(self):
        u = super().command()
        if self.law == 0 or self._time < self.t_enable - 1e-9:
            return u
        return -u
''',
    ),
    "CorePlant": (
        (glider_plant, glider_fmi),
        '''
from glider_plant.slave import GliderPlant


class CorePlant(GliderPlant):
    """GliderPlant without its disturbance inputs and start parameters: the core interface
    and a few outputs more; the disturbances are 0, the start values built in."""

    VARIABLES = tuple(v for v in GliderPlant.VARIABLES
                      if v.name not in ("F_x", "F_z", "M_y", "V_0", "theta_g_0", "alpha_0"))
    F_x = F_z = M_y = 0.0
    V_0, theta_g_0, alpha_0 = 0.2, -0.6108652381980153, 0.017453292519943295
''',
    ),
    "UsualController": (
        (glider_controller, glider_plant, glider_fmi),
        '''
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Real

from glider_controller.laws import passivity_law
from glider_plant.model import equilibrium
from glider_plant.params import GliderParams


class UsualController(Fmi2Slave):
    """The passivity law written the usual pythonfmu way: delta_cmd computed in do_step
    from the inputs of the step's start, and held until the next step."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.V_hat, self.theta_g_hat, self.delta_cmd = 0.2, -0.4, 0.0
        self.register_variable(Real("V_hat", causality=Fmi2Causality.input))
        self.register_variable(Real("theta_g_hat", causality=Fmi2Causality.input))
        self.register_variable(Real("delta_cmd", causality=Fmi2Causality.output))
        self.p = GliderParams()
        self.eq = equilibrium(self.p)

    def do_step(self, current_time, step_size):
        self.delta_cmd = passivity_law(self.V_hat, self.theta_g_hat, 10.0, self.p, self.eq,
                                       math.pi / 2)
        return True
''',
    ),
    "HalfPlant": (
        (),
        '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class HalfPlant(Fmi2Slave):
    """A foreign plant with a part of the interface only."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.delta_cmd = self.V = self.theta_g = 0.0
        self.register_variable(Real("delta_cmd", causality=Fmi2Causality.input))
        self.register_variable(Real("V", causality=Fmi2Causality.output))
        self.register_variable(Real("theta_g", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        return True
''',
    ),
}


@pytest.fixture(scope="module")
def broken(tmp_path_factory) -> dict[str, Path]:
    """FMUs with our interface but a defect, built from small slave scripts on our runtime."""
    from glider_cosim.fmus.python import package_slave
    from glider_fmi.compile import compile_runtime

    out = tmp_path_factory.mktemp("broken_fmus")
    fmus = {}
    with tempfile.TemporaryDirectory() as tmp:
        stage = Path(tmp)
        binary = stage / "runtime.so"
        compile_runtime(binary)
        for name, (packages, source) in BROKEN.items():
            folder = stage / name
            folder.mkdir()
            files = []
            for module in packages:
                dst = folder / module.__name__
                shutil.copytree(Path(module.__file__).parent, dst,
                                ignore=shutil.ignore_patterns("__pycache__", "*.so", "*.c",
                                                              "*.csv"))  # fmt: skip
                files.append(dst)
            script = folder / f"{name}.py"
            script.write_text(source)
            fmus[name] = package_slave(script, out, binary, files)
    return fmus


def _failing(report) -> set[str]:
    return {r.case.name for r in report.results if not r.passed}


def test_a_plant_without_servo_lag_fails_the_servo_cases(broken):
    report = verify(broken["BrokenServoPlant"])
    assert report.component == "plant"
    # tail at 0 (or held at 60 deg) in every other case: there the defect cannot show
    assert _failing(report) == {"core", "servo_jump", "tail_step"}  # core: a 1 deg tail step
    servo = next(r for r in report.results if r.case.name == "servo_jump")
    assert servo.variable == "delta" and servo.time == pytest.approx(0.52)
    assert servo.max_error > 1e4 * servo.tolerance


def test_fmpys_tube_test_would_pass_the_plant_without_servo_lag(broken):
    """The reason for the plain max-error test (README, "Verification kit")."""
    from fmpy.util import validate_result

    fmu = broken["BrokenServoPlant"]
    case = load_case("plant", "servo_jump")
    run = RUNNERS["2.0"](fmu, open_fmu(fmu), case, case.ref_columns[1:])
    dtype = [(n, float) for n in case.ref_columns]
    result = np.rec.fromarrays(run.data.T, dtype=dtype)
    reference = np.rec.fromarrays(case.reference.T, dtype=dtype)
    assert validate_result(result, reference) == 0.0  # no outlier of the tube
    assert not verify(fmu, "plant", "servo_jump").passed


def test_a_controller_with_its_sign_flipped_fails_the_feedback_cases(broken):
    report = verify(broken["FlippedController"])
    assert report.component == "controller"
    assert _failing(report) == set(case_names("controller")) - {"open_loop"}
    with pytest.raises(AssertionError) as err:
        assert_matches_reference(broken["FlippedController"], "controller", "p")
    lines = str(err.value).splitlines()
    assert lines[0] == "1 of 1 controller cases fail:"
    assert lines[1].startswith("FlippedController.fmu: controller case 'p' fails; delta_cmd = ")
    assert "s, reference " in lines[1] and "> tolerance" in lines[1]


def test_outputs_computed_in_do_step_are_named_one_step_late(broken, capsys):
    """Issue 45 item 7: a controller written the usual pythonfmu way fails the passivity
    case at t = 0, equals the reference one step later, and verify says so in one line
    that names the docs paragraph (which exists)."""
    fmu = broken["UsualController"]
    report = verify(fmu)
    assert [r.case.name for r in report.results] == ["passivity"] and not report.passed
    r = report.results[0]
    assert r.variable == "delta_cmd" and r.time == 0.0 and f"{r.max_error:.3g}" == "0.00219"
    assert r.note == ONE_STEP_LATE.format(step=0.02)
    # really one step late: row k + 1 of the run is row k of the reference, bit for bit
    case = load_case("controller", "passivity")
    run = RUNNERS["2.0"](fmu, open_fmu(fmu), case, ["delta_cmd"])
    assert np.array_equal(run.data[1:, 1], case.reference[:-1, 1])
    assert main(["verify", str(fmu)]) == 1
    out = capsys.readouterr().out.splitlines()
    row = next(line for line in out if line.startswith("passivity "))
    assert row.split()[1] == "FAIL" and row.endswith(
        "the outputs equal the reference one step (0.02 s) late: they are computed in doStep, "
        "not from the inputs when read (docs/how-to/verify-a-component.md, 'Where outputs are "
        "computed')"
    )
    page = (Path(__file__).parents[2] / "docs/how-to/verify-a-component.md").read_text()
    assert "\n## Where outputs are computed\n" in page
    # a defect that is not a shift gets no such note
    flipped = verify(broken["FlippedController"])
    assert all("late" not in r.note for r in flipped.results)


def test_cli_table_and_exit_codes(fmu_dir, broken, capsys):
    assert main(["verify", str(fmu_dir / "GliderPlant.fmu"), "--kit"]) == 0
    out = capsys.readouterr().out.splitlines()
    # the header says what was verified: file and SHA-256, flavor, FMI version, binary
    sha = file_sha256(fmu_dir / "GliderPlant.fmu")
    assert out[0].startswith("FMU     ") and out[0].endswith(f"GliderPlant.fmu (sha256 {sha})")
    assert out[1] == "model   GliderPlant: plant, flavor python, FMI 2.0"
    with zipfile.ZipFile(fmu_dir / "GliderPlant.fmu") as z:
        so = hashlib.sha256(z.read("binaries/linux64/GliderPlant.so")).hexdigest()
    assert out[2] == f"binary  binaries/linux64/GliderPlant.so (sha256 {so})"
    assert out[3] == ""
    assert out[4].split() == ["case", "result", "worst", "variable", "max", "error",
                              "tolerance", "at", "t", "(s)", "run", "(s)", "note"]  # fmt: skip
    assert [line.split()[0] for line in out[5:-1]] == case_names("plant")
    assert all(line.split()[1] == "pass" for line in out[5:-1])
    stall = next(line for line in out if line.startswith("stall "))
    assert stall.endswith("fmi2Discard at t = 11.1 s as expected")
    assert out[-1].startswith("plant (GliderPlant, ") and out[-1].endswith("9 of 9 cases pass")
    assert main(["verify", str(broken["BrokenServoPlant"]), "--case", "servo_jump"]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[5].split()[:3] == ["servo_jump", "FAIL", "delta"]
    # looser tolerances given on the command line apply to every case
    code = main(["verify", str(broken["BrokenServoPlant"]), "--case", "tail_step",
                 "--atol", "0.01"])  # fmt: skip
    assert code == 0, capsys.readouterr().out


def test_a_partial_interface_runs_the_cases_it_can_and_lists_the_others(broken, capsys):
    """The core interface and some outputs: the cases it has every variable of run, the
    others are listed as skipped with what they need, and never count as passes."""
    report = verify(broken["CorePlant"])
    assert [r.case.name for r in report.results] == ["core"] and report.passed
    skipped = dict(report.skipped)
    assert sorted(skipped) == sorted(set(case_names("plant")) - {"core"})
    assert skipped["release"] == ["F_x", "F_z", "M_y"]
    assert skipped["tail_step"] == ["F_x", "F_z", "M_y", "V_0", "theta_g_0", "alpha_0"]
    assert main(["verify", str(broken["CorePlant"])]) == 0
    out = capsys.readouterr().out.splitlines()
    assert next(line for line in out if line.startswith("release ")).split()[1:2] == ["skipped"]
    assert next(line for line in out if line.startswith("release ")).endswith("needs F_x, F_z, M_y")
    assert out[-1].endswith(": 1 of 1 cases pass; 8 skipped")
    # one case asked for that it cannot run: nothing ran, exit 2 with what it needs
    assert main(["verify", str(broken["CorePlant"]), "--case", "release"]) == 2
    assert capsys.readouterr().err == (
        "glider-cosim verify: error: FMU 'CorePlant.fmu' (CorePlant) can run none of the "
        "plant cases: release needs F_x, F_z, M_y\n"
    )
    assert_matches_reference(broken["CorePlant"], "plant")  # the core case passes


def test_json_is_the_whole_result_in_one_object(fmu_dir, broken, capsys):
    fmu = fmu_dir / "GliderController.fmu"
    assert main(["verify", str(fmu), "--json", "--kit"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["sha256"] == file_sha256(fmu) and doc["flavor"] == "python"
    assert doc["fmi_version"] == "2.0" and doc["component"] == "controller"
    assert doc["binary"]["path"] == "binaries/linux64/GliderController.so"
    assert doc["passed"] is True and doc["exit_code"] == 0
    assert doc["counts"] == {"passed": 7, "failed": 0, "skipped": 0}
    assert [c["case"] for c in doc["cases"]] == case_names("controller")
    assert {c["result"] for c in doc["cases"]} == {"pass"}
    assert main(["verify", str(broken["BrokenServoPlant"]), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["passed"] is False and doc["exit_code"] == 1
    assert sorted(c["case"] for c in doc["cases"] if c["result"] == "fail") == [
        "core", "servo_jump", "tail_step",
    ]  # fmt: skip
    assert main(["verify", str(broken["HalfPlant"]), "--json"]) == 2
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert doc["exit_code"] == 2 and "lacks the plant core interface" in doc["error"]
    assert captured.err.startswith("glider-cosim verify: error: FMU 'HalfPlant.fmu'")


def test_missing_variables_are_named_in_one_line(fmu_dir, broken, capsys):
    assert main(["verify", str(broken["HalfPlant"])]) == 2
    assert capsys.readouterr().err == (
        "glider-cosim verify: error: FMU 'HalfPlant.fmu' (HalfPlant) lacks the plant core "
        "interface: missing theta_meas (output)\n"
    )
    assert main(["verify", str(broken["HalfPlant"]), "--case", "servo_jump"]) == 2
    assert "missing theta_meas (output)" in capsys.readouterr().err
    assert main(["verify", str(fmu_dir / "GliderPlant.fmu"), "--component", "observer"]) == 2
    assert capsys.readouterr().err == (
        "glider-cosim verify: error: FMU 'GliderPlant.fmu' (GliderPlant) lacks what the loop "
        "requires of the observer: theta_meas (input, rad, is output), theta_g_hat (output, "
        "rad) (docs/reference/fmu-interfaces.md)\n"
    )


def test_an_unknown_case_is_one_line(fmu_dir, capsys):
    assert main(["verify", str(fmu_dir / "GliderObserver.fmu"), "--case", "nope"]) == 2
    assert capsys.readouterr().err == (
        "glider-cosim verify: error: case 'nope' is unknown for the observer: expected one of "
        "filter_step, core, late_start, noisy_pitch, wrong_start\n"
    )
    with pytest.raises(VerifyInputError, match="^case 'nope' is unknown for the observer"):
        assert_matches_reference(fmu_dir / "GliderObserver.fmu", case="nope")


def test_the_component_is_found_from_the_variables(fmu_dir):
    for component, model in COMPONENTS.items():
        report = verify(fmu_dir / f"{model}.fmu", case=DEFAULT_CASE[component])
        assert report.component == component and report.passed


def test_export_writes_the_cross_check_layout(fmu_dir, tmp_path):
    from fmpy import simulate_fmu
    from fmpy.cross_check.validate_vendor_repo import validate_test_fmu
    from fmpy.util import read_csv, read_ref_opt_file

    base = export(tmp_path, fmu_dir)
    assert base.relative_to(tmp_path).parts[:6] == ("fmus", "2.0", "cs", "linux64",
                                                    "glider-cosim", base.name)  # fmt: skip
    for component, model in COMPONENTS.items():
        folder = base / model
        names = {p.name for p in folder.iterdir()}
        assert names == {f"{model}.fmu", f"{model}_in.csv", f"{model}_ref.csv",
                         f"{model}_ref.opt", "ReadMe.txt", "cases"}  # fmt: skip
        assert validate_test_fmu(str(folder)) == []
        assert sorted(p.name for p in (folder / "cases").iterdir()) == sorted(case_names(component))
        default = kit_root() / component / DEFAULT_CASE[component]
        assert (folder / f"{model}_ref.csv").read_bytes() == Path(f"{default}_ref.csv").read_bytes()
        assert "No parameters" in (folder / "ReadMe.txt").read_text()
        # another tool (fmpy's own simulate_fmu) reproduces the exported default case
        opts = read_ref_opt_file(str(folder / f"{model}_ref.opt"))
        ref = read_csv(str(folder / f"{model}_ref.csv"))
        res = simulate_fmu(
            str(folder / f"{model}.fmu"),
            start_time=opts["StartTime"],
            stop_time=opts["StopTime"],
            output_interval=opts["StepSize"],
            step_size=opts["StepSize"],
            input=read_csv(str(folder / f"{model}_in.csv")),
            output=list(ref.dtype.names[1:]),
        )
        # fmpy records an output before it sets the inputs of the same point: the
        # controller's feedthrough output shows there one row late (see the ReadMe.txt)
        lag = 1 if component == "controller" else 0
        assert ("one row later" in (folder / "ReadMe.txt").read_text()) == bool(lag)
        for name in ref.dtype.names[1:]:
            n = min(len(res), len(ref))
            np.testing.assert_allclose(res[name][lag:n], ref[name][: n - lag], rtol=opts["RelTol"],
                                       atol=opts["AbsTol"], err_msg=f"{model}.{name}")  # fmt: skip
    stall = base / "GliderPlant" / "cases" / "stall"
    assert "DiscardTime, 11.1" in (stall / "GliderPlant_ref.opt").read_text()
    assert "V_0,0.2371" in (stall / "GliderPlant_par.csv").read_text()
