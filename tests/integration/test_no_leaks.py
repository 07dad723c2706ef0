"""Nothing leaks: no temporary folder is left by a CLI command, an SSP run, an API call
or a sweep, whether it ends normally, by error, by Ctrl-C or by SIGTERM; SIGTERM is
handled like Ctrl-C (exit 143, results and metrics.json written)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from glider_cosim.interop.ssp_export import export_ssp

pytestmark = pytest.mark.integration
CLI = "from glider_cosim.cli import console_main; console_main()"


def private_env(tmp: Path) -> dict[str, str]:
    """The environment with its own, empty $TMPDIR (and no inherited extraction folder)."""
    tmp.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "GLIDER_COSIM_TMP"}
    env["TMPDIR"] = str(tmp)
    return env


def run(tmp: Path, *args: str, code: str = CLI, cwd: Path | None = None):
    env = private_env(tmp)
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=300)  # fmt: skip


@pytest.fixture(scope="module")
def ssp(fmu_dir: Path, tmp_path_factory) -> Path:
    return export_ssp(tmp_path_factory.mktemp("ssp_leaks") / "glider.ssp", None, fmu_dir)


def test_cli_run_leaves_no_temporary_folder(fmu_dir, tmp_path):
    p = run(tmp_path / "t", "run", "--fmu-dir", str(fmu_dir), "--out", str(tmp_path / "o"),
            "--stop-time", "2", "--no-plots")  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert list((tmp_path / "t").iterdir()) == []


def test_ssp_run_leaves_no_temporary_folder(ssp, tmp_path):
    p = run(tmp_path / "t", "run", str(ssp), "--out", str(tmp_path / "o"), "--stop-time", "2",
            "--no-plots")  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert list((tmp_path / "t").iterdir()) == []


@pytest.mark.parametrize(
    ("args", "code"),
    [
        (["--set", "controller.nosuch=1"], 2),  # refused after the FMUs were unpacked
        (["--fmu-dir", "FMUS", "--set", "plant.z_0=1 deg"], 2),
    ],
)
def test_refused_run_leaves_no_temporary_folder(fmu_dir, tmp_path, args, code):
    args = [str(fmu_dir) if a == "FMUS" else a for a in args]
    p = run(tmp_path / "t", "run", "--fmu-dir", str(fmu_dir), "--out", str(tmp_path / "o"), *args)
    assert p.returncode == code, p.stderr
    assert list((tmp_path / "t").iterdir()) == []


def test_failed_run_leaves_no_temporary_folder(fmu_dir, tmp_path):
    sc = tmp_path / "bad.toml"
    sc.write_text(f"[fmus]\ncontroller = '{fmu_dir / 'GliderController.fmu'}'\n"
                  "[controller]\nK_c = -1.0\n")  # fmt: skip
    p = run(tmp_path / "t", "run", str(sc), "--fmu-dir", str(fmu_dir), "--out", str(tmp_path / "o"))
    assert p.returncode == 1, p.stderr
    assert "K_c = -1.0 is invalid" in p.stderr
    assert list((tmp_path / "t").iterdir()) == []


def test_api_call_leaves_no_temporary_folder(fmu_dir, ssp, tmp_path):
    code = (
        "import sys; from glider_cosim.runner import simulate; "
        "r = simulate('default', None, fmu_dir=sys.argv[1], build=False, stop_time=1.0); "
        "from glider_cosim.interop.ssp_import import load_ssp; "
        "load_ssp(sys.argv[2]); print(r.status)"
    )
    p = run(tmp_path / "t", str(fmu_dir), str(ssp), code=code)
    assert p.returncode == 0 and p.stdout.strip() == "ok", p.stderr
    assert list((tmp_path / "t").iterdir()) == []


@pytest.mark.parametrize(("sig", "exit_code", "text"), [
    (signal.SIGINT, 130, "interrupted; results so far are written"),
    (signal.SIGTERM, 143, "terminated (SIGTERM); results so far are written"),
])  # fmt: skip
def test_signal_stops_the_run_writes_everything_and_leaves_nothing(
    fmu_dir, tmp_path, sig, exit_code, text
):
    tmp = tmp_path / "t"
    out = tmp_path / "o"
    p = subprocess.Popen(
        [sys.executable, "-c", CLI, "run", "--stop-time", "3600", "--out", str(out),
         "--fmu-dir", str(fmu_dir), "--no-plots"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=private_env(tmp),
    )  # fmt: skip
    results = out / "results.csv"
    deadline = time.time() + 60
    while time.time() < deadline and (not results.exists() or results.stat().st_size < 100_000):
        time.sleep(0.1)
    os.kill(p.pid, sig)
    _, err = p.communicate(timeout=60)
    assert p.returncode == exit_code, err
    assert text in err and "Traceback" not in err
    rows = results.read_text().splitlines()
    m = json.loads((out / "metrics.json").read_text())
    assert m["status"] == "interrupted" and m["rows"] == len(rows) - 1 > 100
    expected = "terminated (SIGTERM)" if sig == signal.SIGTERM else "interrupted by the user"
    assert expected in m["message"]
    assert list(tmp.iterdir()) == []


def test_sigterm_during_a_sweep_leaves_nothing(fmu_dir, tmp_path):
    """SIGTERM outside the stepping loop of this process (Dask workers run the FMUs):
    exit 143, the rows so far in sweep.csv, nothing left by the process or its workers."""
    tmp, out = tmp_path / "t", tmp_path / "o"
    p = subprocess.Popen(
        [sys.executable, "-c", CLI, "sweep", "--param", "controller.K_c=2:20:200",
         "--workers", "2", "--stop-time", "10", "--fmu-dir", str(fmu_dir), "--out", str(out),
         "--no-plots"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=private_env(tmp),
    )  # fmt: skip
    table = out / "sweep.csv"
    deadline = time.time() + 120
    while time.time() < deadline and (not table.exists() or table.stat().st_size < 500):
        time.sleep(0.1)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 143, err
    assert "terminated (SIGTERM)" in err and "Traceback" not in err
    assert 1 < len(table.read_text().splitlines()) < 201
    assert list(tmp.iterdir()) == []


def test_sweep_leaves_no_temporary_folder(fmu_dir, tmp_path):
    p = run(tmp_path / "t", "sweep", "--param", "controller.K_c=6,10", "--workers", "1",
            "--stop-time", "1", "--fmu-dir", str(fmu_dir), "--out", str(tmp_path / "o"),
            "--no-plots")  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert list((tmp_path / "t").iterdir()) == []


def test_extractions_are_reused_within_a_process(fmu_dir, tmp_path):
    import shutil

    from glider_cosim.fmus.files import cache_root
    from glider_cosim.inputs.tempdirs import temp_root
    from glider_cosim.master.instance import _extracted

    mine = tmp_path / "GliderPlant.fmu"  # a user's FMU: in the temporary folder
    shutil.copy(fmu_dir / "GliderPlant.fmu", mine)
    a = _extracted(mine)
    b = _extracted(mine)
    assert a == b and Path(a).is_dir()
    assert Path(a).is_relative_to(temp_root())
    # the cache's own: unpacked once for every process, in the cache (issue 48)
    kept = _extracted(fmu_dir / "GliderPlant.fmu")
    assert Path(kept).parent.name == "unpacked" and Path(kept).is_relative_to(cache_root())


def _zig() -> str:
    """zig's own cache folder (the master's C loop may be compiled)."""
    return os.environ.get("ZIG_GLOBAL_CACHE_DIR") or str(Path.home() / ".cache" / "zig")


def _draw_with_matplotlib(tmp_path: Path, fmu_dir: Path, env: dict[str, str], out: str):
    """A command drawing with matplotlib: a two-run sweep (its figures); zig's own cache
    (the master's C loop may be compiled)."""
    env = env | {"ZIG_GLOBAL_CACHE_DIR": _zig()}
    p = subprocess.run([sys.executable, "-c", CLI, "sweep", "--param", "controller.K_c=6,8",
                        "--workers", "1", "--stop-time", "2", "--fmu-dir", str(fmu_dir),
                        "--out", str(tmp_path / out)], capture_output=True, text=True, env=env,
                       timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert (tmp_path / out / "settling_vs_effort.png").is_file()
    return p


def test_cli_keeps_matplotlibs_font_cache_in_our_cache_only(fmu_dir, tmp_path):
    """matplotlib's font cache (the sweep's and report's figures) goes to glider-cosim's
    per-user cache (``<cache>/<version>/matplotlib``, here a fresh ``$GLIDER_COSIM_CACHE``),
    nothing into the home folder, and the next command reuses it (read, not rebuilt)."""
    home = tmp_path / "home"
    home.mkdir()
    env = private_env(tmp_path / "t") | {"HOME": str(home)}
    cache = tmp_path / "cache"  # empty: a font cache found there was written by this test
    env["GLIDER_COSIM_CACHE"] = str(cache)
    for key in ("MPLCONFIGDIR", "XDG_CACHE_HOME", "XDG_CONFIG_HOME"):
        env.pop(key, None)
    _draw_with_matplotlib(tmp_path, fmu_dir, env, "o1")
    from glider_cosim.fmus.files import package_version

    fonts = sorted((cache / package_version() / "matplotlib").glob("fontlist-*.json"))
    assert len(fonts) == 1, sorted(cache.rglob("*"))
    before = fonts[0].stat().st_mtime_ns
    _draw_with_matplotlib(tmp_path, fmu_dir, env, "o2")
    assert fonts[0].stat().st_mtime_ns == before
    # a run's PNGs: matplotlib's too, drawn in the run's process, with the same cache
    p = subprocess.run([sys.executable, "-c", CLI, "run", "--stop-time", "2", "--fmu-dir",
                        str(fmu_dir), "--out", str(tmp_path / "o3")], capture_output=True,
                       text=True, env=env | {"ZIG_GLOBAL_CACHE_DIR": _zig()},
                       timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "o3" / "glide_angle.png").is_file()
    assert fonts[0].stat().st_mtime_ns == before
    assert list(home.rglob("*")) == []
    assert list((tmp_path / "t").iterdir()) == []


def test_cli_without_a_writable_cache_keeps_the_fonts_in_its_temporary_folder(
    fmu_dir, tmp_path
):  # fmt: skip
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the cache would be")
    home = tmp_path / "home"
    home.mkdir()
    env = private_env(tmp_path / "t") | {
        "HOME": str(home),
        "GLIDER_COSIM_CACHE": str(blocker / "cache"),
    }
    env.pop("MPLCONFIGDIR", None)
    _draw_with_matplotlib(tmp_path, fmu_dir, env, "o")
    assert list(home.rglob("*")) == []
    assert list((tmp_path / "t").iterdir()) == []  # the temporary font cache is gone too
