"""The front door: every bad scenario, SSP, FMU file or argument of issue 13 is refused in
one line with exit 2 (before any FMU is instantiated), nothing escapes the output folder,
and the API returns a failed run as a result."""

from __future__ import annotations

import json
import os
import re
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from glider_cosim.cli import main
from glider_cosim.interop.ssp_export import export_ssp
from glider_cosim.runner import simulate
from glider_cosim.scenarios.fields import ScenarioError
from glider_cosim.scenarios.overrides import apply_overrides
from glider_cosim.scenarios.scenario import load_scenario, parse_scenario

pytestmark = pytest.mark.integration
PLANT = "GliderPlant"


def run_cli(capsys, *argv: str) -> tuple[int, str]:
    """``glider-cosim ARGV`` in this process: (exit code, stderr)."""
    capsys.readouterr()
    code = main(list(argv))
    return code, capsys.readouterr().err


def assert_one_line_error(code: int, err: str, *expected: str, command: str = "run") -> None:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"glider-cosim {command}: error: "), err
    assert "Traceback" not in err
    for text in expected:
        assert text in lines[0], lines[0]


@pytest.fixture()
def no_instantiation(monkeypatch):
    """Fails the test if any FMU gets instantiated."""
    from fmpy.fmi2 import FMU2Slave

    calls = []
    monkeypatch.setattr(FMU2Slave, "instantiate", lambda *a, **k: calls.append(a))
    yield
    assert calls == [], "an FMU was instantiated"


# ------------------------------------------------------------------ scenario files
SCENARIO_FINDINGS = [
    ("step = 5e-324", "key-less", "more than the limit of 1000000 (option --max-steps)"),
    ("step = 1e-7", "key-less", "6e+08 steps: more than the limit"),
    ("stop_time = inf", "key 'stop_time'", "expected a finite number"),
    ("stop_time = 1e999", "key 'stop_time'", "expected a finite number"),
    ("[plant]\nnoise_seed = -inf", "key 'plant.noise_seed'", "expected an integer"),
    ("[plant]\nnoise_seed = 1.5", "key 'plant.noise_seed'", "expected an integer"),
    ("[plant]\nnoise_seed = 4294967296", "key 'plant.noise_seed'", "expected an integer in [0,"),
    ("[plant]\nnoise_seed = \"1 deg\"", "key 'plant.noise_seed'",
     "'1 deg' is invalid: noise_seed has no unit: expected a plain number"),
    ("[plant]\nnoise_seed = true", "key 'plant.noise_seed'", "not a boolean"),
    ('record = ["plant.nosuch"]', "record 'plant.nosuch'", "has no variable 'nosuch'"),
    ('record = ["foo.bar"]', "record 'foo.bar'", "no instance 'foo'"),
    ("[controller]\nlaw = 4294967299", "key 'controller.law'", "integer 0..3"),
    ("[controller]\nlaw = 99999999999999999999999", "key 'controller.law'", "integer 0..3"),
    ("[controller]\nlaw = 1.7", "key 'controller.law'", "integer 0..3"),
    ("[controller]\nlaw = true", "key 'controller.law'", "true is invalid"),
    ("[plant]\nalpha_0 = true", "key 'plant.alpha_0'", "not a boolean"),
    ("[plant]\nV_0 = -1.0", "key 'plant.V_0'", "expected a finite value in (0, inf) (m/s)"),
    ("[plant]\nV_0 = \"3 deg\"", "key 'plant.V_0'",
     "'3 deg' is invalid: V_0 is in m/s: expected a number in m/s"),
    ("[controller]\nK_c = \"6 deg\"", "key 'controller.K_c'",
     "'6 deg' is invalid: K_c has no unit: expected a plain number"),
    ("[observer]\nf_cutoff = \"10 kHz\"", "key 'observer.f_cutoff'",
     "'10 kHz' is invalid: f_cutoff is in Hz: expected a number in Hz"),
    ("[controller]\nK_c = -5", "key 'controller.K_c'", "expected a finite value in (0, inf)"),
    ("[plant]\nnosuch = 1", "key 'plant.nosuch'", "has no variable 'nosuch'"),
    ("[plant]\nV = 1", "key 'plant.V'", "it cannot be set"),
    ("[plant]\nK_M0 = -0.39", "key 'plant'", "no descending steady glide"),
    ('[[event]]\nwhen = "time >= nan"\nset = {"controller.K_c" = 3}', "event[0].when",
     "finite number"),
    ('[[event]]\nwhen = "time >= 1e999"\nset = {"controller.K_c" = 3}', "event[0].when",
     "finite number"),
    ('[[event]]\nwhen = "time >= 5 deg"\nset = {"controller.K_c" = 3}', "event[0].when",
     "time is in s"),
    ('[[event]]\nwhen = "plant.z >= 1 deg"\nset = {"controller.K_c" = 3}', "event[0].when",
     "'1 deg' is invalid: z is in m: expected a number in m"),
    ('[[event]]\nwhen = "plant.nosuch >= 1"\nset = {"controller.K_c" = 3}', "event[0]",
     "has no variable 'nosuch'"),
    ('[[event]]\nwhen = "time >= 1"\nset = {"controller.K_c" = -3}', "event[0].set",
     "expected a finite value in (0, inf)"),
    ('[[event]]\nwhen = "time >= 1"\nset = {"controller.law" = 7}', "event[0].set",
     "integer 0..3"),
    ('[inputs]\n"plant.F_z" = "2 deg"', "key 'inputs.plant.F_z'",
     "'2 deg' is invalid: F_z is in N: expected a number in N"),
    ('name = "../../x"', "key 'name'", "is not a name"),
    ('name = "/tmp/abs"', "key 'name'", "is not a name"),
    ('name = ".."', "key 'name'", "is not a name"),
    ("a" * 1_000_000 + " = 1", "unknown key", "(1000000 characters)"),
    ("x = " + "[" * 5000 + "]" * 5000, "not valid TOML", "nested too deeply"),
    ("x = " + "{a = " * 400 + "1" + "}" * 400, "not valid TOML", "nested too deeply"),
    ("[plant]\n" + "a." * 400 + "b = 1", "key", ""),
]  # fmt: skip


@pytest.mark.parametrize(("text", "key", "expected"), SCENARIO_FINDINGS,
                         ids=[t[:40] for t, _, _ in SCENARIO_FINDINGS])  # fmt: skip
def test_bad_scenario_is_refused_in_one_line(
    capsys, fmu_dir, tmp_path, no_instantiation, text, key, expected
):
    path = tmp_path / "s.toml"
    path.write_text(text + "\n")
    out = tmp_path / "out"
    code, err = run_cli(capsys, "run", str(path), "--fmu-dir", str(fmu_dir), "--out", str(out))
    assert_one_line_error(code, err, str(path), expected, *([key] if key != "key-less" else []))
    assert len(err) < 800, "the bad text is quoted to about 200 characters"
    assert not out.exists() or not any(out.iterdir()), "nothing written for a refused run"


SET_FINDINGS = [
    ("plant.noise_seed=inf", "expected an integer"),
    ("plant.noise_seed=-inf", "expected an integer"),
    ("plant.noise_seed=1e400", "expected an integer"),
    ("controller.law=1.7", "or an integer 0..3"),
    ("controller.law=true", "or an integer 0..3"),
    ("controller.law=4294967299", "or an integer 0..3"),
    ("controller.nosuch=3", "has no variable 'nosuch'"),
    ("controller.K_c=-5", "expected a finite value in (0, inf)"),
    ("plant.z_0=1 deg", "'1 deg' is invalid: z_0 is in m: expected a number in m"),
    ("controller.K_c=6 deg", "'6 deg' is invalid: K_c has no unit: expected a plain number"),
    ("plant.V_0=0.2 km/s", "'0.2 km/s' is invalid: V_0 is in m/s: expected a number in m/s"),
    ("plant.V_0=nan", "expected a finite value"),
    ("plant.x=" + "9" * 100_000, "(100008 characters)"),
]


@pytest.mark.parametrize(("item", "expected"), SET_FINDINGS, ids=[s[:30] for s, _ in SET_FINDINGS])
def test_bad_set_is_refused_naming_set(capsys, fmu_dir, tmp_path, no_instantiation, item, expected):
    code, err = run_cli(capsys, "run", "--set", item, "--fmu-dir", str(fmu_dir),
                        "--out", str(tmp_path / "o"))  # fmt: skip
    assert_one_line_error(code, err, "--set '", expected)
    assert "default.toml" not in err, "the error names --set, not the scenario file"
    assert len(err) < 800
    assert not (tmp_path / "o").exists()


ARG_FINDINGS = [
    (["--step", "100"], "--step 100: step 100 s is longer than the run (60 s)"),
    (["--step", "7"], "--step 7: the run (60 s) is not a whole number of steps of 7 s"),
    (["--step", "0.001", "--max-steps", "1000"], "more than the limit of 1000"),
    (["--stop-time", "1e300"], "more than the limit of 1000000"),
    (["--step", "nan"], "expected a finite number > 0"),
    (["--max-steps", "0"], "expected an integer >= 1"),
    (["--max-steps", "1.5"], "expected an integer >= 1"),
    (["--max-extract-mb", "-1"], "expected an integer >= 1"),
    (["--coupling", "magic"], "invalid choice"),
]


@pytest.mark.parametrize(
    ("args", "expected"), ARG_FINDINGS, ids=[" ".join(a) for a, _ in ARG_FINDINGS]
)
def test_bad_argument_is_refused(capsys, fmu_dir, tmp_path, no_instantiation, args, expected):
    try:
        code, err = run_cli(capsys, "run", "--fmu-dir", str(fmu_dir), "--out",
                            str(tmp_path / "o"), *args)  # fmt: skip
    except SystemExit as exit_:  # argparse's own errors
        code, err = exit_.code, capsys.readouterr().err
        assert code == 2 and len(err.strip().splitlines()) == 1 and expected in err, err
        return
    assert_one_line_error(code, err, expected)


def test_values_in_their_declared_units_run(capsys, fmu_dir, tmp_path):
    """'0.2 m/s' for plant.V_0 and '10 Hz' for observer.f_cutoff are those variables' own
    units (issue 28); the run records them as written."""
    out = tmp_path / "out"
    code = main(["run", "--set", "plant.V_0=0.2 m/s", "--set", "observer.f_cutoff=10 Hz",
                 "--set", "plant.theta_g_0=-30 deg", "--stop-time", "0.1", "--no-plots",
                 "--fmu-dir", str(fmu_dir), "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    run = json.loads((out / "metrics.json").read_text())["run"]
    assert run["overrides"] == {"plant.V_0": "0.2 m/s", "observer.f_cutoff": "10 Hz",
                                "plant.theta_g_0": "-30 deg"}  # fmt: skip
    data = np.loadtxt(out / "results.csv", delimiter=",", skiprows=1, ndmin=2)
    cols = (out / "results.csv").read_text().splitlines()[0].split(",")
    assert data[0, cols.index("plant.V")] == pytest.approx(0.2)
    assert data[0, cols.index("plant.theta_g")] == pytest.approx(np.radians(-30))


def test_os_errors_name_the_option(capsys, fmu_dir, tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    cases = [
        (["run", "--out", str(afile), "--fmu-dir", str(fmu_dir)], f"error: --out '{afile}'"),
        (["run", "--out", str(afile / "sub"), "--fmu-dir", str(fmu_dir)], "error: --out"),
        (["run", "--out", "/proc/x", "--fmu-dir", str(fmu_dir)], "error: --out '/proc/x'"),
        (["export-ssp", str(tmp_path), "--fmu-dir", str(fmu_dir)], "error: OUT"),
        (["export-fmu", str(tmp_path), "--fmu-dir", str(fmu_dir)], "error: OUT"),
        (["build", "--out", str(afile)], "error: --out"),
    ]
    for argv, expected in cases:
        code, err = run_cli(capsys, *argv)
        assert_one_line_error(code, err, expected, command=argv[0])
        assert not err.split("error: ", 1)[1].startswith("[Errno"), err


# ------------------------------------------------------------------------- FMUs
def rewrite_zip(src: Path, dst: Path, drop=(), replace=None) -> Path:
    """A copy of the zip ``src`` without the members ``drop``, with ``replace`` members."""
    replace = replace or {}
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for name in zin.namelist():
            if name in drop:
                continue
            zout.writestr(name, replace.get(name, zin.read(name)))
    return dst


def corrupt_deflate(src: Path, dst: Path, member: str) -> Path:
    """A copy of ``src`` whose ``member``'s compressed data is garbled (headers intact)."""
    shutil.copy(src, dst)
    with zipfile.ZipFile(dst) as z:
        info = z.getinfo(member)
    with open(dst, "r+b") as f:
        f.seek(info.header_offset + 26)
        name_len, extra_len = (int.from_bytes(f.read(2), "little") for _ in range(2))
        start = info.header_offset + 30 + name_len + extra_len
        f.seek(start + 2)
        f.write(b"\xff" * min(64, info.compress_size - 4))
    return dst


BINARY = f"binaries/linux64/{PLANT}.so"
FMU_FINDINGS = [
    ("no binary", {"drop": [BINARY]}, "has no binary for this platform"),
    ("garbage binary", {"replace": {BINARY: b"garbage" * 100}}, "not a shared library"),
    ("ELF garbage", {"replace": {BINARY: b"\x7fELF" + b"\0" * 200}}, "cannot be loaded"),
    ("no script", {"drop": [f"resources/{PLANT}.py"]}, "has no script 'resources/GliderPlant.py'"),
    ("no slavemodule", {"drop": ["resources/slavemodule.txt"]}, "no resources/slavemodule.txt"),
    ("no model description", {"drop": ["modelDescription.xml"]}, "has no modelDescription.xml"),
    ("bad model description", {"replace": {"modelDescription.xml": b"<fmi"}},
     "no readable model description"),
    ("corrupt deflate", "deflate", "not a readable zip"),
    ("not a zip", "text", "not a readable zip"),
    ("a folder", "folder", "is not a regular file"),
    ("/dev/zero", "/dev/zero", "is not a regular file"),
    ("missing", "missing", "does not exist"),
]  # fmt: skip


def make_bad_fmu(fmu_dir: Path, tmp_path: Path, how) -> Path:
    good = fmu_dir / f"{PLANT}.fmu"
    bad = tmp_path / "Bad.fmu"
    if how == "deflate":
        return corrupt_deflate(good, bad, "modelDescription.xml")
    if how == "text":
        bad.write_text("not a zip")
        return bad
    if how == "folder":
        bad.mkdir()
        return bad
    if how == "/dev/zero":
        return Path("/dev/zero")
    if how == "missing":
        return tmp_path / "Missing.fmu"
    return rewrite_zip(good, bad, **how)


@pytest.mark.parametrize(
    ("case", "how", "expected"), FMU_FINDINGS, ids=[c for c, _, _ in FMU_FINDINGS]
)
def test_bad_fmu_is_refused_before_loading(
    capsys, fmu_dir, tmp_path, no_instantiation, case, how, expected
):
    bad = make_bad_fmu(fmu_dir, tmp_path, how)
    scenario = tmp_path / "s.toml"
    scenario.write_text(f'[fmus]\nplant = "{bad}"\n')
    code, err = run_cli(capsys, "run", str(scenario), "--fmu-dir", str(fmu_dir),
                        "--out", str(tmp_path / "o"), "--no-plots")  # fmt: skip
    assert_one_line_error(code, err, expected)


# -------------------------------------------------------------------------- SSPs
@pytest.fixture(scope="module")
def ssp(fmu_dir: Path, tmp_path_factory) -> Path:
    return export_ssp(tmp_path_factory.mktemp("ssp13") / "glider.ssp", None, fmu_dir)


def edit_member(ssp: Path, dst: Path, member: str, old: str, new: str) -> Path:
    with zipfile.ZipFile(ssp) as z:
        text = z.read(member).decode()
    assert old in text, old
    return rewrite_zip(ssp, dst, replace={member: text.replace(old, new, 1).encode()})


def nested_fmu(ssp: Path, tmp_path: Path, fmu_dir: Path, how) -> Path:
    bad_fmu = make_bad_fmu(fmu_dir, tmp_path, how)
    return rewrite_zip(ssp, tmp_path / "bad.ssp",
                       replace={f"resources/{PLANT}.fmu": bad_fmu.read_bytes()})  # fmt: skip


def zip_bomb(ssp: Path, dst: Path, n_bytes: int) -> Path:
    """``ssp`` plus a member of ``n_bytes`` zeros (deflated: about n_bytes/1000)."""
    shutil.copy(ssp, dst)
    with zipfile.ZipFile(dst, "a", zipfile.ZIP_DEFLATED) as z, z.open("bomb", "w") as f:
        chunk = bytes(1 << 20)
        for _ in range(n_bytes >> 20):
            f.write(chunk)
    return dst


SSD = "SystemStructure.ssd"
SSP_FINDINGS = [
    ("step 5e-324", lambda s, t, f: edit_member(s, t / "b.ssp", SSD, 'baseStepSize="0.02"',
                                                'baseStepSize="5e-324"'), (), "--max-steps"),
    ("step 1e-300", lambda s, t, f: edit_member(s, t / "b.ssp", SSD, 'baseStepSize="0.02"',
                                                'baseStepSize="1e-300"'), (), "--max-steps"),
    ("integer overflow", lambda s, t, f: edit_member(s, t / "b.ssp", SSD, '<ssv:Integer value="1"',
                                                     '<ssv:Integer value="4294967297"'), (),
     "value '4294967297' is not a valid Integer"),
    ("source ../", lambda s, t, f: edit_member(s, t / "b.ssp", SSD,
                                               'source="resources/GliderPlant.fmu"',
                                               f'source="../../../../../../{f}/GliderPlant.fmu"'),
     (), "points outside the SSP"),
    ("source absolute", lambda s, t, f: edit_member(s, t / "b.ssp", SSD,
                                                    'source="resources/GliderPlant.fmu"',
                                                    f'source="{f}/GliderPlant.fmu"'),
     (), "expected a path relative to the SSP"),
    ("source file:///", lambda s, t, f: edit_member(s, t / "b.ssp", SSD,
                                                    'source="resources/GliderPlant.fmu"',
                                                    f'source="file://{f}/GliderPlant.fmu"'),
     (), "expected a path relative to the SSP"),
    ("source http:", lambda s, t, f: edit_member(s, t / "b.ssp", SSD,
                                                 'source="resources/GliderPlant.fmu"',
                                                 'source="http://x/GliderPlant.fmu"'),
     (), "expected a path relative to the SSP"),
    ("K_c out of range", lambda s, t, f: edit_member(s, t / "b.ssp", SSD,
                                                     '<ssv:Real value="10.0" />',
                                                     '<ssv:Real value="-5.0" />'), (),
     "component 'controller': parameter 'K_c': -5.0 is invalid: expected a finite value in"),
    ("law out of range", lambda s, t, f: edit_member(s, t / "b.ssp", SSD,
                                                     '<ssv:Integer value="1" />',
                                                     '<ssv:Integer value="7" />'), (),
     "parameter 'law': 7 is invalid: expected an integer in [0, 3]"),
    ("corrupt deflate", lambda s, t, f: corrupt_deflate(s, t / "b.ssp", SSD), (),
     "not a readable SSP archive"),
    ("zip bomb, default limit", lambda s, t, f: zip_bomb(s, t / "b.ssp", 300 << 20), (),
     "unpacks to more than 268435456 bytes"),
    ("zip bomb, --max-extract-mb", lambda s, t, f: zip_bomb(s, t / "b.ssp", 20 << 20),
     ("--max-extract-mb", "10"), "unpacks to more than 10485760 bytes"),
    ("FMU without binary", lambda s, t, f: nested_fmu(s, t, f, {"drop": [BINARY]}), (),
     "has no binary for this platform"),
    ("FMU garbage binary", lambda s, t, f: nested_fmu(s, t, f, {"replace": {BINARY: b"x" * 99}}),
     (), "not a shared library"),
    ("FMU without script", lambda s, t, f: nested_fmu(s, t, f,
                                                      {"drop": [f"resources/{PLANT}.py"]}),
     (), "has no script"),
    ("FMU without slavemodule", lambda s, t, f: nested_fmu(
        s, t, f, {"drop": ["resources/slavemodule.txt"]}), (), "no resources/slavemodule.txt"),
    ("FMU corrupt", lambda s, t, f: nested_fmu(s, t, f, "deflate"), (), "not a readable zip"),
    ("a FIFO", lambda s, t, f: _fifo(t), (), "is not a regular file"),
]  # fmt: skip


def _fifo(tmp_path: Path) -> Path:
    path = tmp_path / "fifo.ssp"
    os.mkfifo(path)
    return path


@pytest.mark.parametrize(("case", "make", "args", "expected"), SSP_FINDINGS,
                         ids=[c[0] for c in SSP_FINDINGS])  # fmt: skip
def test_bad_ssp_is_refused_in_one_line(
    capsys, ssp, fmu_dir, tmp_path, no_instantiation, case, make, args, expected
):
    bad = make(ssp, tmp_path, fmu_dir)
    code, err = run_cli(capsys, "run", str(bad), "--out", str(tmp_path / "o"), "--no-plots", *args)
    assert_one_line_error(code, err, expected)


def test_zip_bomb_is_not_left_on_disk(ssp, tmp_path, capsys):
    from glider_cosim.inputs.tempdirs import temp_root

    bad = zip_bomb(ssp, tmp_path / "b.ssp", 20 << 20)
    before = set(temp_root().iterdir())
    code, err = run_cli(capsys, "run", str(bad), "--max-extract-mb", "10", "--no-plots")
    assert code == 2, err
    assert set(temp_root().iterdir()) == before, "the partial extraction was removed"
    assert not any(p.name == "bomb" for p in temp_root().rglob("*"))


# ---------------------------------------------------------------------- escapes
def test_a_run_writes_only_in_its_out_folder(fmu_dir, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, err = run_cli(capsys, "run", "--fmu-dir", str(fmu_dir), "--stop-time", "1", "--no-plots")
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["default"]


# ------------------------------------------------------------------------- the API
def test_api_returns_a_failed_run_as_a_result(fmu_dir):
    sc = apply_overrides(load_scenario("default"), {"plant.V_0": -1.0})
    r = simulate(sc, out=None, fmu_dir=fmu_dir, build=False)
    assert r.status == "error"
    assert "V_0 = -1.0 is invalid" in r.message, r.message
    assert r.data.shape == (0, len(r.columns)) and r.metrics["status"] == "error"


def test_api_failed_run_with_out_writes_metrics_and_no_empty_csv(fmu_dir, tmp_path):
    sc = apply_overrides(load_scenario("default"), {"controller.K_c": -5.0})
    r = simulate(sc, out=tmp_path, fmu_dir=fmu_dir, build=False)
    assert r.status == "error" and "K_c" in r.message
    assert json.loads((tmp_path / "metrics.json").read_text())["status"] == "error"
    assert not (tmp_path / "results.csv").exists()


@pytest.mark.parametrize(
    ("overrides", "error"),
    [
        ({"controller.law": 1.7}, "expected an integer"),
        ({"plant.alpha_0": True}, "not a boolean"),
        ({"plant.nosuch": 1.0}, "has no variable 'nosuch'"),
    ],
)
def test_api_bad_arguments_raise_a_typed_error(fmu_dir, overrides, error, no_instantiation):
    sc = apply_overrides(load_scenario("default"), overrides)
    with pytest.raises(ValueError, match=error):
        simulate(sc, out=None, fmu_dir=fmu_dir, build=False)


def test_api_refuses_too_many_steps_before_building(tmp_path):
    with pytest.raises(ValueError, match="more than the limit of 10"):
        simulate("default", out=None, fmu_dir=tmp_path / "none", max_steps=10)
    assert not (tmp_path / "none").exists()


def test_scenario_names_are_names():
    for bad in ("../x", "/abs", "a/b", "..", ".hidden", "", "x" * 101, "a\0b"):
        with pytest.raises(ScenarioError, match="is not a name"):
            parse_scenario({"name": bad})
    assert parse_scenario({"name": "fig2-open_loop.v1+x"}).name == "fig2-open_loop.v1+x"


# ----------------------------------------------------------------------- help texts
@pytest.mark.parametrize("command", ["run", "sweep", "build", "export-ssp", "report"])
def test_help_is_plain_text_with_defaults(command, capsys):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = capsys.readouterr().out
    assert "``" not in text and ":class:" not in text
    assert "(default: " in text or command == "export-ssp"
    if command == "run":
        assert ".ssp" in text
        for option in ("--coupling", "--no-plots", "--max-steps", "--max-extract-mb"):
            block = text.split(option, 1)[1].split("\n  -", 1)[0]
            assert len(block.split()) > 3, f"{option} has no help"
    if command == "sweep":
        for option in ("--format", "--no-plots"):
            block = text.split(option, 1)[1].split("\n  -", 1)[0]
            assert len(block.split()) > 3, f"{option} has no help"


def test_summary_line_has_rounded_times(fmu_dir, tmp_path, capsys):
    capsys.readouterr()
    code = main(["run", "--fmu-dir", str(fmu_dir), "--stop-time", "59.99", "--step", "0.01",
                 "--out", str(tmp_path), "--no-plots"])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0
    assert "to t = 59.99 s" in out and "step 0.01 s" in out, out
    assert "0000000" not in out


def test_quote_bounds_the_text():
    from glider_cosim.inputs.text import quote

    assert quote("x" * 10) == "'xxxxxxxxxx'"
    long = quote("y" * 10_000)
    assert len(long) < 260 and long.endswith("(10000 characters)")
    deep: list = []
    for _ in range(100_000):
        deep = [deep]
    assert "nested" in quote(deep)
    assert quote(True) == "true"


def test_a_fifo_scenario_is_not_read(tmp_path, capsys):
    fifo = tmp_path / "s.toml"
    os.mkfifo(fifo)
    code, err = run_cli(capsys, "run", str(fifo))
    assert_one_line_error(code, err, "is not a regular file")


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"scenario": 123}, TypeError, "expected a Scenario, a path"),
        ({"step": True}, TypeError, "step true is invalid"),
        ({"stop_time": "60"}, TypeError, "stop_time '60' is invalid"),
        ({"max_steps": 0}, ValueError, "max_steps 0 is invalid"),
        ({"coupling": "sideways"}, ValueError, "coupling 'sideways' is unknown"),
        ({"step": -0.02}, ValueError, "step = -0.02 s is invalid"),
        ({"scenario": "nope"}, ValueError, "scenario file does not exist"),
    ],
)
def test_api_argument_errors_are_typed(fmu_dir, kwargs, error, message, no_instantiation):
    kwargs = {"scenario": "default", **kwargs}
    with pytest.raises(error, match=re.escape(message)):
        simulate(out=None, fmu_dir=fmu_dir, build=False, **kwargs)


# ------------------------------------------------------------------ issue 28, point 6
def test_api_overrides_take_what_set_takes(fmu_dir):
    r = simulate(None, overrides={"controller.K_c": 6, "plant.theta_g_0": "-30 deg",
                                  "plant.V_0": "0.2 m/s"}, stop_time=0.1,
                 fmu_dir=fmu_dir)  # fmt: skip
    assert r.status == "ok", r.message
    assert r.metrics["run"]["overrides"] == {"controller.K_c": 6, "plant.theta_g_0": "-30 deg",
                                             "plant.V_0": "0.2 m/s"}  # fmt: skip
    assert r.column("plant.theta_g")[0] == pytest.approx(np.radians(-30))


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"controller.K_c": "6 deg"}, "overrides['controller.K_c']: '6 deg' is invalid: K_c has "
         "no unit: expected a plain number"),
        ({"controller.K_x": 6}, "overrides['controller.K_x']: instance controller "
         "(GliderController) has no variable 'K_x'"),
    ],
)  # fmt: skip
def test_api_overrides_are_refused_before_instantiation(fmu_dir, no_instantiation, overrides,
                                                        message):  # fmt: skip
    with pytest.raises(ValueError) as err:
        simulate(None, overrides=overrides, stop_time=0.1, fmu_dir=fmu_dir)
    assert str(err.value).startswith(message)


def test_a_failed_run_names_the_command(fmu_dir, tmp_path, capsys):
    """The run's failure line has the one prefix form too (exit 1)."""
    code = main(["run", "--set", "controller.K_c=0.05", "--stop-time", "3", "--no-plots",
                 "--fmu-dir", str(fmu_dir), "--out", str(tmp_path)])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 1
    assert err.startswith(
        "glider-cosim run: error: run stopped: observer: fmi2DoStep at t = 2.58 s returned "
        "fmi2Discard: "
    ), err
    assert err.count("\n") == 1
