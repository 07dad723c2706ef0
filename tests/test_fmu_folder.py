"""Nothing of the user's is written over in an FMU folder (issue 45): the folder's record
``.glider-cosim-fmus.json`` of what glider-cosim built there, and the refusals of a
foreign, changed or corrupt FMU and of a set of another FMI version or flavor, on every
command that builds into a folder. The FMUs here are small zip files that look like ours
(their provenance resources) or like a user's: every refusal comes before anything is
built. Real builds (the record's contents, ``--overwrite-fmus``, a swapped FMU in the
folder): tests/integration/test_fmu_folder_builds.py."""

from __future__ import annotations

import hashlib
import json
import zipfile
from pathlib import Path

import pytest

from glider_cosim.cli import main
from glider_cosim.fmus import record
from glider_cosim.fmus.folders import FmuFolderError, build_all, in_cache
from glider_cosim.fmus.record import RECORD_FILE

NAMES = ("GliderPlant", "GliderObserver", "GliderController")
MD = '<?xml version="1.0"?>\n<fmiModelDescription fmiVersion="{v}.0" modelName="{n}"/>\n'


def fake_fmu(path: Path, ours: bool, fmi: int = 2, flavor: str = "python") -> Path:
    """A zip that reads like an FMU: with our provenance resources if ``ours``."""
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("modelDescription.xml", MD.format(v=fmi, n=path.stem))
        if ours:
            z.writestr("resources/glider_cosim_flavor.txt", flavor + "\n")
            z.writestr(record.HASH_FILES[(flavor, fmi)], "0" * 64 + "\n")
            if flavor == "native":
                z.writestr(record.PLATFORMS_FILE, "x86_64-linux\n")
    return path


def our_set(
    folder: Path, fmi: int = 2, flavor: str = "python", recorded: bool = True, names=NAMES
) -> Path:
    """FMUs ``names`` that look like ours (an old, stale build), with a record if
    ``recorded``."""
    folder.mkdir(parents=True, exist_ok=True)
    for n in names:
        fake_fmu(folder / f"{n}.fmu", True, fmi, flavor)
    if recorded:
        record.write_record(folder, {f"{n}.fmu": record.entry_for(folder / f"{n}.fmu")
                                     for n in names})  # fmt: skip
    return folder


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def cli(capsys, *argv: str) -> tuple[int, str]:
    capsys.readouterr()
    code = main(list(argv))
    return code, capsys.readouterr().err


def one_line_error(err: str, command: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"glider-cosim {command}: error: "), err
    return lines[0]


#: every command that builds our FMUs into a folder the user names
COMMANDS = {
    "run": ["run", "--no-plots", "--stop-time", "1", "--out", "{tmp}/o", "--fmu-dir", "{d}"],
    "run --flavor native": [
        "run",
        "--no-plots",
        "--flavor",
        "native",
        "--out",
        "{tmp}/o",
        "--fmu-dir",
        "{d}",
    ],  # fmt: skip
    "sweep": ["sweep", "--param", "controller.K_c=4,6", "--out", "{tmp}/s", "--fmu-dir", "{d}"],
    "export-ssp": ["export-ssp", "{tmp}/x.ssp", "--fmu-dir", "{d}"],
    "export-fmu": ["export-fmu", "{tmp}/x.fmu", "--fmu-dir", "{d}"],
    "report": ["report", "--out", "{tmp}/r", "--fmu-dir", "{d}", "--no-progress"],
    "verify --export": ["verify", "--export", "{tmp}/e", "--fmu-dir", "{d}"],
    "build --out": ["build", "--out", "{d}"],
}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_users_fmu_beside_ours_is_not_written_over(command, tmp_path, capsys):
    d = our_set(tmp_path / "D", names=NAMES[:2])  # a set built with the controller swapped
    mine = fake_fmu(d / "GliderController.fmu", ours=False)  # the user's own controller
    before = snapshot(d)
    argv = [a.format(tmp=tmp_path, d=d) for a in COMMANDS[command]]
    code, err = cli(capsys, *argv)
    assert code == 2
    line = one_line_error(err, argv[0])
    option = "--out" if argv[0] == "build" else "--fmu-dir"
    assert f"{option} '{d}': GliderController.fmu was not built there by glider-cosim" in line
    assert "use another folder or pass --overwrite-fmus to replace it with ours" in line or (
        "use another folder, pass --overwrite-fmus to replace it with ours or name it in a "
        "scenario's [fmus] table to run it" in line
    ), line
    assert snapshot(d) == before, "nothing in the folder changed"
    assert mine.read_bytes() == before["GliderController.fmu"]


def test_a_users_fmu_copied_over_ours_is_not_written_over(tmp_path, capsys):
    d = our_set(tmp_path / "D")  # all three built by glider-cosim
    fake_fmu(d / "GliderController.fmu", ours=False)  # then the user's copied over ours
    before = snapshot(d)
    code, err = cli(capsys, "run", "--no-plots", "--fmu-dir", str(d), "--out", str(tmp_path / "o"))
    assert code == 2
    assert (
        f"--fmu-dir '{d}': GliderController.fmu changed since glider-cosim built it (its "
        f"SHA-256 is not the one in {RECORD_FILE}): it is not written over; use another folder, "
        "pass --overwrite-fmus to replace it with ours or name it in a scenario's [fmus] table "
        "to run it"
    ) in one_line_error(err, "run")
    assert snapshot(d) == before


def test_a_users_fmu_in_a_folder_without_a_record_is_not_written_over(tmp_path, capsys):
    d = our_set(tmp_path / "D", recorded=False)  # written before the record existed
    fake_fmu(d / "GliderController.fmu", ours=False)
    before = snapshot(d)
    code, err = cli(capsys, "run", "--no-plots", "--fmu-dir", str(d), "--out", str(tmp_path / "o"))
    assert code == 2 and "GliderController.fmu was not built there" in one_line_error(err, "run")
    assert snapshot(d) == before and not (tmp_path / "o").exists()


@pytest.mark.parametrize("recorded", [True, False])
@pytest.mark.parametrize(
    ("asked", "shown"),
    [(["--fmi", "3", "--flavor", "native"], "FMI 3.0 native"), (["--fmi", "3"], "FMI 3.0 python"),
     (["--flavor", "native"], "FMI 2.0 native")],
)  # fmt: skip
def test_an_fmi2_set_is_not_converted_in_place(asked, shown, recorded, tmp_path, capsys):
    d = our_set(tmp_path / "D", recorded=recorded)  # what `glider-cosim build` wrote
    before = snapshot(d)
    code, err = cli(capsys, "run", "--no-plots", *asked, "--fmu-dir", str(d),
                    "--out", str(tmp_path / "o"))  # fmt: skip
    assert code == 2
    line = one_line_error(err, "run")
    assert (
        f"--fmu-dir '{d}' holds FMI 2.0 python FMUs (GliderPlant.fmu, GliderObserver.fmu, "
        f"GliderController.fmu), not the {shown} ones asked for: a set is not converted in "
        "place; use another folder (or none: the per-user cache) or pass --overwrite-fmus"
    ) in line
    assert snapshot(d) == before


def test_build_out_does_not_convert_an_fmi3_native_set(tmp_path, capsys):
    d = our_set(tmp_path / "D", fmi=3, flavor="native")
    before = snapshot(d)
    code, err = cli(capsys, "build", "--out", str(d))  # python, FMI 2 by default
    assert code == 2
    line = one_line_error(err, "build")
    assert f"--out '{d}' holds FMI 3.0 native FMUs" in line
    assert "not the FMI 2.0 python ones asked for" in line and "per-user cache" not in line
    assert snapshot(d) == before


def test_a_changed_fmu_is_refused(tmp_path, capsys):
    d = our_set(tmp_path / "D")
    with zipfile.ZipFile(d / "GliderObserver.fmu", "a") as z:  # edited by another tool
        z.writestr("resources/extra.txt", "mine")
    before = snapshot(d)
    code, err = cli(capsys, "run", "--no-plots", "--fmu-dir", str(d), "--out", str(tmp_path / "o"))
    assert code == 2
    line = one_line_error(err, "run")
    assert (
        f"--fmu-dir '{d}': GliderObserver.fmu changed since glider-cosim built it (its SHA-256 "
        f"is not the one in {RECORD_FILE}): it is not written over; use another folder, pass "
        "--overwrite-fmus to replace it with ours"
    ) in line
    assert snapshot(d) == before


@pytest.mark.parametrize("recorded", [True, False])
def test_a_corrupt_fmu_is_refused(recorded, tmp_path, capsys):
    d = our_set(tmp_path / "D", recorded=recorded)
    (d / "GliderPlant.fmu").write_bytes((d / "GliderPlant.fmu").read_bytes()[:100])  # cut short
    before = snapshot(d)
    code, err = cli(capsys, "export-ssp", str(tmp_path / "x.ssp"), "--fmu-dir", str(d))
    assert code == 2
    line = one_line_error(err, "export-ssp")
    if recorded:
        assert "GliderPlant.fmu changed since glider-cosim built it" in line
        assert "it is no longer a readable FMU" in line
    else:
        assert (
            "GliderPlant.fmu is not a readable FMU (not a zip archive with a "
            "modelDescription.xml) and glider-cosim did not build it there" in line
        )
    assert snapshot(d) == before and not (tmp_path / "x.ssp").exists()


def test_a_users_osp_description_beside_ours_is_refused(tmp_path, capsys):
    d = our_set(tmp_path / "D")
    (d / "GliderPlant_OspModelDescription.xml").write_text("<mine/>\n")
    before = snapshot(d)
    code, err = cli(capsys, "run", "--no-plots", "--fmu-dir", str(d), "--out", str(tmp_path / "o"))
    assert code == 2
    line = one_line_error(err, "run")
    assert "GliderPlant_OspModelDescription.xml was not built there by glider-cosim" in line
    assert "[fmus]" not in line  # not an FMU: nothing to swap in
    assert snapshot(d) == before


def test_an_unreadable_record_is_refused(tmp_path, capsys):
    d = our_set(tmp_path / "D")
    (d / RECORD_FILE).write_text("{not json")
    before = snapshot(d)
    code, err = cli(capsys, "build", "--out", str(d))
    assert code == 2
    line = one_line_error(err, "build")
    assert f"--out '{d}': {RECORD_FILE}, glider-cosim's record of the FMUs it built there" in line
    assert "--overwrite-fmus" in line
    assert snapshot(d) == before


def test_the_api_raises_a_value_error_naming_the_file(tmp_path):
    d = tmp_path / "D"
    d.mkdir()
    fake_fmu(d / "GliderPlant.fmu", ours=False)
    with pytest.raises(FmuFolderError, match="GliderPlant.fmu was not built there") as err:
        build_all(d, only_stale=True)
    assert isinstance(err.value, ValueError)
    assert snapshot(d)["GliderPlant.fmu"] == (d / "GliderPlant.fmu").read_bytes()


def test_the_survey_judges_each_file(tmp_path):
    d = our_set(tmp_path / "D")
    fake_fmu(d / "GliderController.fmu", ours=False)
    (d / "GliderObserver.fmu").write_bytes(b"not a zip")
    names = [f"{n}.fmu" for n in NAMES]
    held = record.survey(d, names, record.read_record(d))
    assert {k: h.state for k, h in held.items()} == {
        "GliderPlant.fmu": "ours", "GliderPlant_OspModelDescription.xml": "missing",
        "GliderObserver.fmu": "changed", "GliderObserver_OspModelDescription.xml": "missing",
        "GliderController.fmu": "changed",
        "GliderController_OspModelDescription.xml": "missing",
    }  # fmt: skip
    assert (held["GliderPlant.fmu"].flavor, held["GliderPlant.fmu"].fmi) == ("python", 2)
    plant = (d / "GliderPlant.fmu").read_bytes()
    assert held["GliderPlant.fmu"].sha256 == hashlib.sha256(plant).hexdigest()
    # without a record: the provenance decides, and the OSP file beside an FMU of ours
    (d / RECORD_FILE).unlink()
    (d / "GliderPlant_OspModelDescription.xml").write_text("<x/>")
    (d / "GliderController_OspModelDescription.xml").write_text("<x/>")
    held = record.survey(d, names, None)
    assert {k: h.state for k, h in held.items()} == {
        "GliderPlant.fmu": "ours", "GliderPlant_OspModelDescription.xml": "ours",
        "GliderObserver.fmu": "corrupt", "GliderObserver_OspModelDescription.xml": "missing",
        "GliderController.fmu": "foreign",
        "GliderController_OspModelDescription.xml": "foreign",
    }  # fmt: skip


def test_an_osp_description_left_without_a_record_is_ours(tmp_path):
    """A checkout's fmus/ (the OSP-IS files of an old build, tracked in git), or a folder
    whose FMUs were deleted to rebuild them: the OSP-IS files there are ours."""
    d = tmp_path / "fmus"
    d.mkdir()
    from glider_cosim.fmus.osp import NS

    osp = d / "GliderPlant_OspModelDescription.xml"  # the root element OSP-IS's builds write
    osp.write_text(f'<?xml version="1.0" encoding="UTF-8"?>\n<OspModelDescription xmlns="{NS}" '
                   'version="1.0"><UnitDefinitions/></OspModelDescription>\n')  # fmt: skip
    (d / "GliderController_OspModelDescription.xml").write_text("<OspModelDescription/>")
    held = record.survey(d, [f"{n}.fmu" for n in NAMES], None)
    assert held[osp.name].state == "ours"
    assert held["GliderController_OspModelDescription.xml"].state == "foreign"  # not OSP-IS's
    assert record.survey(d, ["GliderPlant.fmu"], {})[osp.name].state == "foreign"  # recorded


def test_the_record_is_written_in_one_step_and_reads_back(tmp_path):
    d = our_set(tmp_path / "D")
    data = json.loads((d / RECORD_FILE).read_text())
    assert data["format"] == 1 and set(data["files"]) == {f"{n}.fmu" for n in NAMES}
    entry = data["files"]["GliderPlant.fmu"]
    assert entry == {
        "sha256": hashlib.sha256((d / "GliderPlant.fmu").read_bytes()).hexdigest(),
        "flavor": "python", "fmi": 2, "source_hash": "0" * 64,
    }  # fmt: skip
    assert record.read_record(d) == data["files"]
    assert [p.name for p in d.iterdir() if p.name.endswith(".part")] == []


def test_the_cache_is_glider_cosims_own(tmp_path, monkeypatch):
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path / "cache"))
    assert in_cache(tmp_path / "cache" / "0.1.0" / "python-abc")
    assert not in_cache(tmp_path / "D")


def test_the_flag_and_its_default_are_in_the_help(capsys):
    for command in ("run", "sweep", "export-ssp", "export-fmu", "report", "build", "verify"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "--overwrite-fmus" in text, command
        assert "(default: off: such a folder is refused, naming the file;" in text, command


def test_builds_into_one_folder_take_turns(tmp_path):
    import subprocess
    import sys

    probe = ("import sys, filelock\ntry:\n    filelock.FileLock(sys.argv[1]).acquire(timeout=0)\n"
             "except filelock.Timeout:\n    sys.exit(3)\n")  # fmt: skip
    d = tmp_path / "D"
    lock = str(record.lock_file(d))
    with record.locked(d):  # what build_all holds while it checks, builds and records
        held = subprocess.run([sys.executable, "-c", probe, lock], timeout=60)
    free = subprocess.run([sys.executable, "-c", probe, lock], timeout=60)
    assert (held.returncode, free.returncode) == (3, 0)
