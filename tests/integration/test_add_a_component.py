"""docs/how-to/add-a-component.md runs as written (issue 55 item 3), in a fresh clone of
the project's committed state with its own virtual environment (the system's packages
visible, the clone installed over them): each line of every ``sh`` block is run in the
clone and must exit 0, a TOML block whose first line names a file is written there, and
the page's ``text`` blocks are what the run, the verification and ``git status`` print.
Then no file of the project but the new folder, the registry line and the scenario
changed, the noise block sits between the plant and the observer, and the project's own
layout and packaging checks still pass with a fourth component registered."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.integration
ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "how-to" / "add-a-component.md"


def blocks() -> list[tuple[str, str]]:
    """The page's fenced blocks with a language, in order, as (language, text)."""
    return re.findall(r"^```(\w+)\n(.*?)^```", PAGE.read_text(), flags=re.M | re.S)


def _run(line: str, cwd: Path, env: dict[str, str]) -> str:
    p = subprocess.run(line, shell=True, cwd=cwd, env=env, capture_output=True, text=True,
                       timeout=900, check=False)  # noqa: S602 # fmt: skip
    assert p.returncode == 0, f"{line}: {p.stdout[-2000:]}{p.stderr[-2000:]}"
    return p.stdout


@pytest.fixture(scope="module")
def walked(tmp_path_factory) -> tuple[Path, dict[str, str], dict[str, str]]:
    """The page walked through in a fresh clone: (the clone, its environment, each shell
    line -> its stdout)."""
    if not (ROOT / ".git").exists() or shutil.which("git") is None:
        pytest.skip("not a git checkout: the page is walked in a clone of it")
    tmp = tmp_path_factory.mktemp("add-a-component")
    clone, venv = tmp / "glider-cosim", tmp / "venv"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True, timeout=300)
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)],
                   check=True, timeout=300)  # fmt: skip
    env = {**os.environ, "VIRTUAL_ENV": str(venv),
           "PATH": f"{venv / 'bin'}{os.pathsep}{os.environ['PATH']}"}  # fmt: skip
    env.pop("PYTHONPATH", None)
    out: dict[str, str] = {}
    for language, text in blocks():
        named = re.match(r"# ([\w-]+\.toml)\b", text)
        if language == "toml" and named:
            (clone / named.group(1)).write_text(text)
        elif language == "sh":
            for line in text.strip().splitlines():
                out[line] = _run(line, clone, env)
        elif language not in ("text", "toml"):
            pytest.fail(f"{PAGE.name}: a {language} block this test does not know how to run")
    return clone, env, out


def test_the_page_runs_as_written_and_prints_what_it_says(walked):
    clone, _, out = walked
    texts = [t for language, t in blocks() if language == "text"]
    assert len(texts) == 4, "the page shows the run, the two verifications and git status"
    run, reference, carried, status = texts
    printed = out["glider-cosim run noisy-pitch.toml"]
    for line in run.strip().splitlines():
        assert line in printed.splitlines(), f"the run did not print {line!r}:\n{printed}"
    assert out["python -m glider_cosim.verify.reference --component noise"] == reference
    verified = out["glider-cosim verify fmus/GliderPitchNoise.fmu"]
    assert verified.strip().splitlines()[-1] == carried.strip()
    assert "smoke-test.exp [experiment/smoke-test] experiment 'reference': pass" in verified
    shown = subprocess.run(["git", "status", "--short"], cwd=clone, capture_output=True,
                           text=True, check=True).stdout  # fmt: skip
    assert shown == status, "files other than the folder, the registry line and the scenario"


def test_the_reference_case_is_checked_not_trusted(walked):
    """A reference output that the FMU does not give fails the page's verification."""
    clone, env, _ = walked
    ref = clone / "src" / "noise" / "reference_output.csv"
    good = ref.read_text()
    try:
        lines = good.splitlines(keepends=True)
        t, v = lines[2].split(",")
        lines[2] = f"{t},{float(v) + 1e-6!r}\n"  # one output 1e-6 rad off
        ref.write_text("".join(lines))
        p = subprocess.run(["python", "-m", "glider_cosim.verify.reference", "--component",
                            "noise"], cwd=clone, env=env, capture_output=True, text=True,
                           timeout=600, check=False)  # fmt: skip
        assert p.returncode == 1 and "differs from reference_output.csv" in p.stdout, p.stdout
    finally:
        ref.write_text(good)


def test_nothing_else_changed(walked):
    """Every file of the project but the three is as committed, untracked ones included
    (``--untracked-files=all``; ignored ones are the run's output and build leftovers)."""
    clone = walked[0]
    status = ["git", "status", "--porcelain", "--untracked-files=all"]
    shown = subprocess.run(status, cwd=clone, capture_output=True, text=True, check=True).stdout
    changed = {line[3:] for line in shown.splitlines()}
    example = ROOT / "docs" / "how-to" / "add-a-component" / "noise"
    folder = {f"src/noise/{p.relative_to(example).as_posix()}" for p in example.rglob("*")
              if p.is_file() and "__pycache__" not in p.parts}  # fmt: skip
    assert changed == {"cosim/components.toml", "noisy-pitch.toml", *folder}
    diff = subprocess.run(["git", "diff", "-U0", "cosim/components.toml"], cwd=clone,
                          capture_output=True, text=True, check=True).stdout  # fmt: skip
    added = [x for x in diff.splitlines() if x.startswith("+") and not x.startswith("+++")]
    removed = [x for x in diff.splitlines() if x.startswith("-") and not x.startswith("---")]
    assert (added, removed) == (['+noise = "src/noise"'], [])


def test_the_noise_block_sits_between_plant_and_observer(walked):
    """The results' new column is the plant's pitch plus the bias (0.5 deg) and the noise
    (0.02 deg): the figures the page quotes."""
    clone = walked[0]
    results = clone / "out" / "noisy-pitch" / "results.csv"
    data = np.genfromtxt(results, delimiter=",", names=True, deletechars="")
    diff = np.degrees(data["noise.theta_out"] - data["plant.theta_meas"])[1:]
    assert f"{diff.mean():.3f}" == "0.500"
    assert f"{diff.std():.3f}" == "0.020"
    text = PAGE.read_text()
    assert "0.500\ndeg" in text or "0.500 deg" in text
    assert "0.020 deg" in text


def test_the_projects_own_checks_pass_with_a_fourth_component(walked):
    """The registry, layout and packaging checks of the clone, with the noise block
    registered: nothing in them lists the components by hand."""
    clone, env, _ = walked
    tests = [
        "tests/test_components.py",
        "tests/test_layout.py",
        "tests/test_packaging.py",
        "tests/test_messages.py",
    ]
    p = subprocess.run(["python", "-m", "pytest", "-q", "-p", "no:cacheprovider", *tests],
                       cwd=clone, env=env, capture_output=True, text=True, timeout=600,
                       check=False)  # fmt: skip
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-2000:]
    assert " passed" in p.stdout


def test_fmpy_runs_the_added_fmu_as_its_reference_case_says(walked):
    """fmpy, not our master, judges the FMU the page built: it validates, and
    ``simulate_fmu`` on the reference inputs gives the reference outputs. fmpy reads the
    outputs after each step, before it sets the next input, so with ``theta_out`` fed
    through from ``theta_in`` its row k holds the noise of step k on the input of row
    k-1."""
    from fmpy import simulate_fmu
    from fmpy.validation import validate_fmu

    clone = walked[0]
    fmu, folder = clone / "fmus" / "GliderPitchNoise.fmu", clone / "src" / "noise"
    assert validate_fmu(str(fmu)) == []
    inp = np.genfromtxt(folder / "reference_input.csv", delimiter=",", names=True)
    ref = np.genfromtxt(folder / "reference_output.csv", delimiter=",", names=True)
    signals = np.array(list(zip(inp["time"], inp["theta_in"], strict=True)),
                       dtype=[("time", float), ("theta_in", float)])  # fmt: skip
    params = tomllib.loads((folder / "component.toml").read_text())["reference"]["parameters"]
    got = simulate_fmu(str(fmu), stop_time=10.0, step_size=0.02, output_interval=0.02,
                       input=signals, start_values=params, output=["theta_out"])  # fmt: skip
    assert len(got) == len(ref) == 501
    assert got["theta_out"][0] == ref["theta_out"][0]
    held = ref["theta_out"][1:] - inp["theta_in"][1:] + inp["theta_in"][:-1]
    assert np.max(np.abs(got["theta_out"][1:] - held)) <= 1e-12
    assert np.max(np.abs(got["theta_out"] - ref["theta_out"])) > 1e-4  # the rows do differ
