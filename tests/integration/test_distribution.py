"""The distribution from a clean export: the wheel holds every module and data file, the
sdist what the wheel needs; runs from an empty folder leave it empty (FMUs go to the
per-user cache); two processes building into one empty cache both get valid FMUs.

The install of the wheel into a fresh virtual environment, outside the checkout, is a
step of ``.ci/run`` (it downloads nothing that CI has not installed already, but takes
about a minute)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from setup_args import setup_kwargs

pytestmark = pytest.mark.integration
ROOT = Path(__file__).resolve().parents[2]
CLI = "from glider_cosim.cli import console_main; console_main()"


def tracked_files() -> list[str]:
    """The checkout's files under version control (paths relative to the root)."""
    if not (ROOT / ".git").exists() or shutil.which("git") is None:
        pytest.skip("not a git checkout")
    out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True)
    return [f for f in out.stdout.decode().split("\0") if f and (ROOT / f).is_file()]


def package_files() -> dict[str, str]:
    """Every tracked file under a package root -> its path in the wheel."""
    dirs = setup_kwargs()["package_dir"]  # setup.py's, from the component registry
    roots = {root.rstrip("/") + "/": name for name, root in dirs.items()}
    out = {}
    for f in tracked_files():
        for root, name in roots.items():
            if f.startswith(root):
                out[f] = name + "/" + f[len(root) :]
    return out


@pytest.fixture(scope="module")
def export(tmp_path_factory) -> Path:
    """The tracked files only, as ``git archive`` or a clean clone would give them."""
    dest = tmp_path_factory.mktemp("export") / "glider-cosim"
    for f in tracked_files():
        (dest / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / f, dest / f)
    return dest


@pytest.fixture(scope="module")
def wheel(export, tmp_path_factory) -> Path:
    dist = tmp_path_factory.mktemp("wheel")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(dist),
                    str(export)], check=True, capture_output=True, timeout=300)  # fmt: skip
    (whl,) = dist.glob("glider_cosim-*.whl")
    return whl


def test_the_wheel_holds_every_module_and_data_file(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    wanted = package_files()
    missing = sorted(f for f, w in wanted.items() if w not in names)
    assert not missing, f"tracked files missing from the wheel: {missing[:10]}"
    for must in ("glider_cosim/inputs/check.py", "glider_fmi/fmi2_layer.c",
                 "glider_plant/plant_model.c", "glider_plant/plant_model.h",
                 "glider_cosim/master/fastloop.c", "glider_cosim/scenarios/default.toml",
                 "glider_cosim/verification/plant/stall_ref.csv",
                 "glider_controller/reference_output.csv"):  # fmt: skip
        assert must in names
    assert not [n for n in names if "__pycache__" in n or n.endswith((".so", ".fmu"))]


def test_the_sdist_holds_what_the_wheel_needs(export, tmp_path):
    code = "import sys; from setuptools import build_meta as b; print(b.build_sdist(sys.argv[1]))"
    p = subprocess.run([sys.executable, "-c", code, str(tmp_path)], cwd=export,
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    (sdist,) = tmp_path.glob("glider?cosim-*.tar.gz")  # "-" before setuptools 69.3
    import tarfile

    with tarfile.open(sdist) as t:
        top = sdist.name.removesuffix(".tar.gz")
        members = {m.name.removeprefix(top + "/") for m in t.getmembers() if m.isfile()}
    missing = sorted(f for f in [*package_files(), "pyproject.toml", "README.md"]
                     if f not in members)  # fmt: skip
    assert not missing, f"files the wheel needs missing from the sdist: {missing[:10]}"


def _outside_env(tmp_path: Path) -> dict[str, str]:
    """The environment of a user with an empty cache in ``tmp_path`` (not the session's)."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("GLIDER_COSIM_CACHE", "GLIDER_COSIM_TMP")}  # fmt: skip
    env["XDG_CACHE_HOME"] = str(tmp_path / "cache")
    return env


def test_cli_and_api_from_an_empty_folder_leave_it_empty(tmp_path):
    here = tmp_path / "here"
    here.mkdir()
    env = _outside_env(tmp_path)
    runs = [
        [sys.executable, "-c", CLI, "run", "--no-plots", "--stop-time", "1",
         "--out", str(tmp_path / "out")],
        [sys.executable, "-c", CLI, "export-ssp", str(tmp_path / "glider.ssp")],
        [sys.executable, "-c", "from glider_cosim.runner import simulate; "
         "r = simulate(None, None, stop_time=1.0); assert r.status == 'ok', r.status"],
    ]  # fmt: skip
    for cmd in runs:
        p = subprocess.run(cmd, cwd=here, env=env, capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, (cmd[3:], p.stderr[-2000:])
        assert list(here.iterdir()) == [], cmd[3:]
    # the run's set for this machine alone (issue 48), the export's and the API's full set
    folders = sorted((tmp_path / "cache" / "glider-cosim").glob("*/python-*"))
    assert [f.name.startswith("python-only-") for f in folders] == [False, True], folders
    names = ["GliderController", "GliderObserver", "GliderPlant"]
    for folder in folders:
        assert sorted(f.name for f in folder.iterdir()) == sorted(
            [f"{n}.fmu" for n in names]
            + [f"{n}_OspModelDescription.xml" for n in names]
            + [".glider-cosim-fmus.json"]
        )  # each FMU and its OSP-IS file beside it, and the record of what was built there


@pytest.mark.parametrize("flavor", ["python", "native"])
def test_two_concurrent_builds_into_one_empty_cache_give_valid_fmus(tmp_path, flavor):
    env = _outside_env(tmp_path)
    code = (
        "import sys; from glider_cosim.fmus.folders import prepare_fmus; "
        "print(prepare_fmus(None, sys.argv[1]))"
    )
    procs = [subprocess.Popen([sys.executable, "-c", code, flavor], env=env, text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for _ in range(2)]  # fmt: skip
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [e[-2000:] for _, e in outs]
    folders = {Path(o.strip()) for o, _ in outs}
    assert len(folders) == 1
    (folder,) = folders
    names = ["GliderController", "GliderObserver", "GliderPlant"]
    assert sorted(f.name for f in folder.iterdir()) == sorted(
        [f"{n}.fmu" for n in names]
        + [f"{n}_OspModelDescription.xml" for n in names]
        + [".glider-cosim-fmus.json"]
    )  # each FMU and its OSP-IS file beside it, and the record of what was built there
    from glider_cosim.fmus import native
    from glider_cosim.fmus.python import COMPONENTS, is_current

    for fmu in folder.glob("*.fmu"):
        with zipfile.ZipFile(fmu) as z:
            assert z.testzip() is None
            assert "modelDescription.xml" in z.namelist()
    if flavor == "python":
        assert all(is_current(folder / f"{c.name}.fmu", c) for c in COMPONENTS)
    else:
        assert all(native.is_current(folder / f"{c.name}.fmu", c)
                   for c in native.NATIVE_COMPONENTS)  # fmt: skip
