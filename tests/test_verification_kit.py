"""The verification kit's data (fast tier: no FMU is built or run)."""

from __future__ import annotations

import fnmatch
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy.util import read_ref_opt_file
from setup_args import setup_kwargs

from glider_cosim.cli import main
from glider_cosim.verify import (
    COMPONENTS,
    VerifyInputError,
    case_names,
    kit_files,
    kit_root,
    load_case,
    verify,
)
from glider_cosim.verify.cases import CORE, DEFAULT_CASE
from glider_cosim.verify.compare import check_tolerance, compare
from glider_cosim.verify.run import Run

ROOT = Path(__file__).resolve().parents[1]
ALL = [(c, n) for c in COMPONENTS for n in case_names(c)]
INPUTS = {
    "plant": ["delta_cmd", "F_x", "F_z", "M_y"],
    "observer": ["theta_meas", "delta_cmd"],
    "controller": ["V_hat", "theta_g_hat"],
}


def test_every_case_the_issue_asks_for_is_there():
    assert set(case_names("plant")) == {"release", "tail_step", "servo_jump", "noise_seed",
                                        "pulse_fx", "pulse_fz", "pulse_my", "stall",
                                        "core"}  # fmt: skip
    assert set(case_names("observer")) == {"filter_step", "wrong_start", "noisy_pitch",
                                           "late_start", "core"}  # fmt: skip
    assert set(case_names("controller")) == {"open_loop", "passivity", "p", "pi", "saturation",
                                             "anti_windup", "enable_time"}  # fmt: skip
    assert all(case_names(c)[0] == DEFAULT_CASE[c] for c in COMPONENTS)


@pytest.mark.parametrize(("component", "name"), ALL)
def test_case_files_parse_at_50_hz(component, name):
    case = load_case(component, name)
    assert case.step == 0.02 and case.start == 0.0
    # every input of the component, or (a case of the core interface) the core's only
    core = [n for n, c in CORE[component].items() if c == "input"]
    assert case.input_columns in (["time", *INPUTS[component]], ["time", *core])
    n = round(case.stop / case.step)
    np.testing.assert_allclose(case.inputs[:, 0], np.arange(n + 1) * 0.02, atol=1e-9)
    ref_end = case.stop if case.discard_time is None else case.discard_time
    m = round(ref_end / case.step)
    np.testing.assert_allclose(case.reference[:, 0], np.arange(m + 1) * 0.02, atol=1e-9)
    assert set(case.ref_columns[1:]).isdisjoint(case.input_columns)
    assert case.rtol >= 0 and case.atol > 0
    # fmpy's cross-check reader accepts the options file as it is
    assert read_ref_opt_file(str(case.folder / f"{name}_ref.opt"))["StepSize"] == 0.02


def test_only_the_stall_case_ends_with_a_discard():
    ends = {(c, n): load_case(c, n).discard_time for c, n in ALL}
    assert {k: v for k, v in ends.items() if v is not None} == {("plant", "stall"): 11.1}


def test_parameters_are_data():
    """Every parameter is a name and a literal (number or true/false): nothing to run."""
    for path in kit_root().glob("*/*_par.csv"):
        rows = path.read_text().splitlines()
        assert rows[0] == "name,value"
        for row in rows[1:]:
            name, value = row.split(",")
            assert re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name), row
            assert value in ("true", "false") or re.fullmatch(r"-?\d+(\.\d+)?(e-?\d+)?", value)
    assert load_case("plant", "noise_seed").parameters["noise_seed"] == "7"


def test_the_readmes_list_every_case_with_its_tolerances():
    for component in COMPONENTS:
        text = (kit_root() / component / "README.md").read_text()
        rows = re.findall(r"^\| `([a-z0-9_]+)` \| (.+?) \| (\S+) \| (\S+) \| (.+) \|$", text, re.M)
        assert sorted(r[0] for r in rows) == sorted(case_names(component))
        for name, _purpose, rtol, atol, _why in rows:
            case = load_case(component, name, with_reference=False)
            assert (float(rtol), float(atol)) == (case.rtol, case.atol), name


def test_the_kit_is_small():
    total = sum(p.stat().st_size for p in kit_files())
    assert total < 2 * 2**20, total


def test_every_kit_file_is_package_data():
    """Every file of the kit matches a package-data pattern of glider_cosim (in the wheel)."""
    given = setup_kwargs()
    patterns = given["package_data"]["glider_cosim"]
    assert given["package_dir"]["glider_cosim"] == "cosim"
    files = kit_files(ROOT / "cosim" / "verification")
    assert len(files) == 3 + sum(3 + (c.parameters != {}) for c in map(
        lambda cn: load_case(*cn, with_reference=False), ALL))  # fmt: skip
    for f in files:
        rel = f.relative_to(ROOT / "cosim").as_posix()
        assert any(fnmatch.fnmatch(rel, p) for p in patterns), rel
    # and the installed package finds them where the kit looks
    assert {p.name for p in kit_files()} == {p.name for p in files}


def _case(discard: float | None = 11.1):
    case = load_case("plant", "stall")
    case.discard_time = discard
    return case


def _run(case, n_rows: int, stop=None):
    return Run(case.ref_columns, case.reference[:n_rows].copy(), stop)


def test_the_stall_passes_with_a_discard_within_one_step():
    case = _case()
    n = len(case.reference)
    for t in (11.08, 11.1, 11.12):
        r = compare(case, _run(case, n, ("discard", t, "stalled")))
        assert r.passed, r.describe()
    assert (
        "fmi2Discard at t = 11.1 s as expected"
        in compare(case, _run(case, n, ("discard", 11.1, "x"))).note
    )


def test_the_stall_fails_without_the_discard_or_at_another_time():
    case = _case()
    n = len(case.reference)
    r = compare(case, _run(case, n))
    assert not r.passed and "expected fmi2Discard at t = 11.1 s, ran to the stop time" in r.note
    r = compare(case, _run(case, n - 5, ("discard", 11.0, "x")))
    assert not r.passed
    assert "fmi2Discard at t = 11 s, expected at 11.1 s (within one step, 0.02 s)" in r.note
    r = compare(case, _run(case, n, ("error", 11.1, "boom")))
    assert not r.passed and "boom" in r.note


def test_a_wrong_value_is_described_with_case_variable_time_and_values():
    case = load_case("controller", "p")
    run = Run(case.ref_columns, case.reference.copy())
    run.data[100, 1] += 1e-3
    r = compare(case, run)
    assert not r.passed and r.variable == "delta_cmd" and r.time == pytest.approx(2.0)
    text = r.describe("X.fmu")
    assert text.startswith("X.fmu: controller case 'p' fails; delta_cmd = ")
    assert "at t = 2 s, reference " in text and "error 0.001 > tolerance" in text
    assert compare(case, run, atol=2e-3).passed


def test_outputs_one_step_late_are_named_as_such():
    """Issue 45 item 7: outputs equal to the reference shifted by one step get a one-line
    note naming the docs paragraph; other errors, and a shift by two steps, do not."""
    case = load_case("controller", "passivity")
    late = Run(case.ref_columns, case.reference.copy())
    late.data[1:, 1] = case.reference[:-1, 1]
    late.data[0, 1] = 0.0
    r = compare(case, late)
    assert not r.passed and r.time == 0.0 and f"{r.max_error:.3g}" == "0.00219"
    assert r.note == (
        "the outputs equal the reference one step (0.02 s) late: they are computed in doStep, "
        "not from the inputs when read (docs/how-to/verify-a-component.md, 'Where outputs are "
        "computed')"
    )
    two = Run(case.ref_columns, case.reference.copy())
    two.data[2:, 1] = case.reference[:-2, 1]
    assert compare(case, two).note == ""
    off = Run(case.ref_columns, case.reference.copy())
    off.data[100, 1] += 1e-3
    assert compare(case, off).note == ""


@pytest.mark.parametrize("bad", ["-1", "nan", "inf", "x", ""])
def test_a_bad_tolerance_is_one_line(bad, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["verify", "any.fmu", "--rtol", bad])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err == (
        f"glider-cosim verify: error: argument --rtol: {bad!r} is invalid: expected a finite "
        "number >= 0\n"
    )
    with pytest.raises(VerifyInputError, match=r"^atol .* is invalid: expected a finite"):
        check_tolerance(bad if bad else -1.0, "atol")


def test_not_an_fmu_is_one_line(capsys, tmp_path):
    text = tmp_path / "notes.fmu"
    text.write_text("hello")
    assert main(["verify", str(text)]) == 2
    assert capsys.readouterr().err == (
        "glider-cosim verify: error: FMU 'notes.fmu' is not a readable zip (File is not a zip "
        "file)\n"
    )
    assert main(["verify", str(tmp_path / "missing.fmu")]) == 2
    assert capsys.readouterr().err == (
        f"glider-cosim verify: error: FMU {tmp_path / 'missing.fmu'} does not exist\n"
    )


def test_an_ssp_is_named_as_an_ssp_with_what_to_pass_instead(capsys, tmp_path):
    """Issue 45 item 9: an SSP (or its .ssd) is not an FMU, and verify says which FMUs to
    pass instead."""
    ssp = tmp_path / "glider.ssp"
    with zipfile.ZipFile(ssp, "w") as z:
        z.writestr("SystemStructure.ssd", "<ssd:SystemStructureDescription/>")
        z.writestr("resources/GliderPlant.fmu", b"")
        z.writestr("resources/GliderController.fmu", b"")
    assert main(["verify", str(ssp)]) == 2
    assert capsys.readouterr().err == (
        "glider-cosim verify: error: 'glider.ssp' is an SSP (a system of FMUs), not an FMU: "
        "verify one of its FMUs (resources/GliderPlant.fmu, resources/GliderController.fmu, "
        f"unzipped from it); run the whole system with glider-cosim run {ssp}\n"
    )
    ssd = tmp_path / "SystemStructure.ssd"
    ssd.write_text("<ssd:SystemStructureDescription/>")
    with pytest.raises(VerifyInputError) as err:
        verify(ssd)
    assert str(err.value) == (
        "'SystemStructure.ssd' is an SSP system description (.ssd), not an FMU: verify one of "
        f"its FMUs; run the whole system with glider-cosim run {ssd}"
    )


def test_an_fmi1_fmu_is_refused_in_one_line(capsys, tmp_path):
    fmu = tmp_path / "One.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.writestr("modelDescription.xml", '<fmiModelDescription fmiVersion="1.0"/>')
    assert main(["verify", str(fmu)]) == 2
    assert capsys.readouterr().err == (
        "glider-cosim verify: error: FMU 'One.fmu' is an FMI 1.0 FMU: this build runs FMI "
        "2.0, 3.0 co-simulation FMUs\n"
    )


def test_an_unknown_component_is_one_line(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["verify", "x.fmu", "--component", "rudder"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "argument --component: invalid choice: 'rudder'" in err
    with pytest.raises(VerifyInputError, match="^component 'rudder' is unknown: expected one of"):
        verify("x.fmu", "rudder")


def test_verify_needs_an_fmu_or_a_command(capsys):
    assert main(["verify"]) == 2
    assert capsys.readouterr().err == (
        "glider-cosim verify: error: expected an FMU (or --write-references, --export DIR)\n"
    )


@pytest.mark.parametrize("component", COMPONENTS)
def test_the_core_is_in_every_case_and_one_case_needs_only_the_core(component):
    core = CORE[component].items()
    cases = {n: load_case(component, n).variables.items() for n in case_names(component)}
    assert [n for n, v in cases.items() if not core <= v] == []
    assert [n for n, v in cases.items() if v <= core], f"no {component} case of the core only"


def test_the_readme_lists_each_core_interface():
    """docs "Verify a component": one line per component, inputs -> outputs, as CORE."""
    text = (ROOT / "docs" / "how-to" / "verify-a-component.md").read_text()
    for component, core in CORE.items():
        ins = ", ".join(f"`{n}`" for n, c in core.items() if c == "input")
        outs = ", ".join(f"`{n}`" for n, c in core.items() if c == "output")
        line = f"| {component} | {ins} | {outs} |"
        assert line in text, line
    assert re.search(r"\| component \| core inputs \| core outputs \|", text)
