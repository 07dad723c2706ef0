"""Nothing of the user's is written over in an FMU folder (issue 45), with real builds
(the Python flavor, FMI 2.0: about 8 s a set):

- ``build --out D`` writes the record ``.glider-cosim-fmus.json``: each FMU with its
  SHA-256, flavor, FMI version and source hash (the one a rebuild compares), each OSP-IS
  description with its SHA-256; ``run --fmu-dir D`` then writes nothing there, and
  ``run --fmi 3 --flavor native`` refuses the FMI 2.0 set instead of converting it;
- a user's own controller FMU in ``D`` is refused, its bytes kept; ``--overwrite-fmus``
  replaces it with ours and records it;
- a user's controller named ``GliderController.fmu`` in ``D`` and swapped in by a
  scenario's ``[fmus]`` table runs, untouched, beside our plant and observer;
- a folder written before the record existed runs as it is (its FMUs carry our
  provenance) and gets no record while nothing is built;
- in the per-user cache (glider-cosim's own) a corrupt FMU is rebuilt, with a warning.

The refusals without a build (foreign, changed, corrupt, other sets, every command):
tests/test_fmu_folder.py."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from glider_cosim.fmus.files import fmu_flavor
from glider_cosim.fmus.python import COMPONENTS, HASH_FILE, source_hash
from glider_cosim.fmus.record import RECORD_FILE, file_sha256

pytestmark = pytest.mark.integration
SRC = Path(__file__).parent / "fmus_src"
NAMES = ("GliderPlant", "GliderObserver", "GliderController")
RUN = ("run", "--no-plots", "--stop-time", "1")


def cli(*args: str, cwd: Path | None = None, env: dict | None = None):
    return subprocess.run(
        [sys.executable, "-c", "from glider_cosim.cli import console_main; console_main()", *args],
        capture_output=True, text=True, cwd=cwd, env=env, timeout=600,
    )  # fmt: skip


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    """``glider-cosim build --out D``: a Python FMI 2.0 set with its record."""
    d = tmp_path_factory.mktemp("built") / "D"
    p = cli("build", "--out", str(d))
    assert p.returncode == 0, p.stderr
    return d


@pytest.fixture(scope="module")
def users_controller(tmp_path_factory) -> Path:
    """A controller that is not ours (a plain P law, SwapTestController.py)."""
    from glider_cosim.fmus.python import build_slave_fmu

    return build_slave_fmu(SRC / "SwapTestController.py", tmp_path_factory.mktemp("mine"))


def test_build_writes_the_record_of_what_it_built(built):
    data = json.loads((built / RECORD_FILE).read_text())
    assert data["format"] == 1 and data["glider_cosim"]
    files = data["files"]
    assert set(files) == {f"{n}{s}" for n in NAMES for s in (".fmu", "_OspModelDescription.xml")}
    for c in COMPONENTS:
        fmu = built / f"{c.name}.fmu"
        entry = files[fmu.name]
        assert entry["sha256"] == file_sha256(fmu)
        assert (entry["flavor"], entry["fmi"]) == ("python", 2)
        assert entry["source_hash"] == source_hash(c)  # what a rebuild compares
        with zipfile.ZipFile(fmu) as z:
            assert z.read(HASH_FILE).decode().strip() == entry["source_hash"]
        osp = built / f"{c.name}_OspModelDescription.xml"
        assert files[osp.name] == {"sha256": file_sha256(osp)}
    assert not [p for p in built.iterdir() if p.name.endswith(".part")]


def test_a_run_writes_nothing_and_an_fmi3_run_converts_nothing(built, tmp_path):
    before = snapshot(built)
    p = cli(*RUN, "--fmu-dir", str(built), "--out", str(tmp_path / "o"))
    assert p.returncode == 0, p.stderr
    assert snapshot(built) == before
    p = cli(*RUN, "--fmi", "3", "--flavor", "native", "--fmu-dir", str(built),
            "--out", str(tmp_path / "o3"))  # fmt: skip
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1
    assert (
        f"glider-cosim run: error: --fmu-dir '{built}' holds FMI 2.0 python FMUs "
        "(GliderPlant.fmu, GliderObserver.fmu, GliderController.fmu), not the FMI 3.0 native "
        "ones asked for: a set is not converted in place"
    ) in p.stderr
    assert snapshot(built) == before  # an fmpy script on this FMI 2.0 set still runs
    assert not (tmp_path / "o3").exists()


def test_a_users_controller_is_refused_and_the_flag_replaces_it(built, users_controller, tmp_path):
    d = tmp_path / "D"
    shutil.copytree(built, d)
    mine = d / "GliderController.fmu"
    shutil.copyfile(users_controller, mine)  # the user's own, over ours
    before = snapshot(d)
    p = cli(*RUN, "--fmu-dir", str(d), "--out", str(tmp_path / "o"))
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1
    assert f"--fmu-dir '{d}': GliderController.fmu changed since glider-cosim built it" in p.stderr
    assert "--overwrite-fmus" in p.stderr
    assert snapshot(d) == before
    p = cli(*RUN, "--fmu-dir", str(d), "--out", str(tmp_path / "o"), "--overwrite-fmus")
    assert p.returncode == 0, p.stderr
    assert mine.read_bytes() != before["GliderController.fmu"]
    assert fmu_flavor(mine) == "python"  # ours again
    entry = json.loads((d / RECORD_FILE).read_text())["files"]["GliderController.fmu"]
    assert entry["sha256"] == file_sha256(mine)
    assert snapshot(d)["GliderPlant.fmu"] == before["GliderPlant.fmu"]  # the rest kept


def test_a_users_controller_swapped_in_by_the_scenario_runs_untouched(
    built, users_controller, tmp_path
):
    d = tmp_path / "D"
    d.mkdir()
    for n in NAMES[:2]:
        shutil.copyfile(built / f"{n}.fmu", d / f"{n}.fmu")  # ours (no record: provenance)
    mine = d / "GliderController.fmu"
    shutil.copyfile(users_controller, mine)
    scenario = d / "mine.toml"
    scenario.write_text('feedback = "state"\nwith_observer = false\n[controller]\nK_P = 0.5\n'
                        '[fmus]\ncontroller = "GliderController.fmu"\n')  # fmt: skip
    before = mine.read_bytes()
    for extra in ([], ["--flavor", "python"]):
        out = tmp_path / f"o{len(extra)}"
        p = cli(*RUN, str(scenario), "--fmu-dir", str(d), "--out", str(out), *extra)
        assert p.returncode == 0, p.stderr
        assert mine.read_bytes() == before
        fmus = json.loads((out / "metrics.json").read_text())["run"]["fmus"]
        assert fmus["controller"]["model_name"] == "SwapTestController"
        assert fmus["plant"]["model_name"] == "GliderPlant"


def test_a_folder_without_a_record_runs_as_it_is(built, tmp_path):
    d = tmp_path / "D"
    shutil.copytree(built, d)
    (d / RECORD_FILE).unlink()  # written before the record existed
    before = snapshot(d)
    p = cli(*RUN, "--fmu-dir", str(d), "--out", str(tmp_path / "o"))
    assert p.returncode == 0, p.stderr
    assert snapshot(d) == before  # current: nothing built, so no record either


def test_build_into_a_checkouts_fmus_folder(tmp_path):
    """The checkout's fmus/ holds the OSP-IS files of an old build (tracked in git), no
    FMU and no record: ``glider-cosim build`` builds there as before."""
    root = Path(__file__).resolve().parents[2]
    shutil.copytree(root / "fmus", tmp_path / "fmus")
    p = cli("build", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    files = json.loads((tmp_path / "fmus" / RECORD_FILE).read_text())["files"]
    assert len(files) == 6


def test_a_corrupt_fmu_in_the_cache_is_rebuilt_with_a_warning(built, tmp_path):
    env = {**os.environ, "GLIDER_COSIM_CACHE": str(tmp_path / "cache")}
    p = cli(*RUN, "--out", str(tmp_path / "o"), env=env)
    assert p.returncode == 0, p.stderr
    (plant,) = (tmp_path / "cache").glob("*/python-*/GliderPlant.fmu")
    plant.write_bytes(b"not a zip")
    p = cli(*RUN, "--out", str(tmp_path / "o"), env=env)
    assert p.returncode == 0, p.stderr
    assert "GliderPlant.fmu': not the file glider-cosim built in its cache (changed): rebuilt" in (
        p.stderr
    )
    assert zipfile.is_zipfile(plant)
    entry = json.loads((plant.parent / RECORD_FILE).read_text())["files"]["GliderPlant.fmu"]
    assert entry["sha256"] == file_sha256(plant)
