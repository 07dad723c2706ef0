"""Every wait over two seconds shows what is being done and how far (issue 45), through
the command line: plain lines on stderr in a pipe (one per step, no carriage return), a
bar on a terminal (a pty), nothing with ``--quiet``. The first run's build into an empty
cache, ``build``, ``run --real-time``, ``sweep`` and ``report``."""

from __future__ import annotations

import fcntl
import os
import pty
import re
import select
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

from glider_cosim.fmus.files import package_version
from glider_fmi import toolchain

pytestmark = pytest.mark.integration

HOST = toolchain.host_platform()
STEP = re.compile(r"\((\d+) of (\d+)\)$")
#: what marks CI (glider_cosim.progress.CI_VARIABLES): left out, so a terminal gets its bar
CI = ("CI", "GITHUB_ACTIONS", "GITLAB_CI", "BUILDKITE", "JENKINS_URL", "TF_BUILD")


def _env(cache: Path | None = None) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in CI}
    env["TERM"] = "xterm"
    if cache is not None:
        env["GLIDER_COSIM_CACHE"] = str(cache)
    return env


def _cli(args: list[str], cache: Path | None = None) -> subprocess.CompletedProcess:
    """``glider-cosim ARGS`` with stdout and stderr pipes (no terminal, no CI)."""
    p = subprocess.run([sys.executable, "-m", "glider_cosim.cli", *args], capture_output=True,
                       text=True, env=_env(cache), timeout=600)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    return p


def _cli_on_a_terminal(args: list[str], cache: Path | None = None) -> str:
    """What ``glider-cosim ARGS`` writes on stderr when it is a terminal (80 columns)."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    proc = subprocess.Popen([sys.executable, "-m", "glider_cosim.cli", *args], stderr=slave,
                            stdout=subprocess.DEVNULL, stdin=subprocess.DEVNULL,
                            env=_env(cache))  # fmt: skip
    os.close(slave)
    chunks = []
    while select.select([master], [], [], 600)[0]:
        try:
            data = os.read(master, 65536)
        except OSError:  # the command ended: its end of the pty is closed
            break
        if not data:
            break
        chunks.append(data)
    os.close(master)
    text = b"".join(chunks).decode(errors="replace")
    assert proc.wait(timeout=60) == 0, text[-3000:]
    return text


def _steps(lines: list[str]) -> list[tuple[int, int]]:
    return [(int(m[1]), int(m[2])) for m in map(STEP.search, lines) if m]


def _without_zig_notes(stderr: str) -> list[str]:
    """The lines of ``stderr`` but zig's one-time notes (a machine whose zig cache is cold
    gets them; tests/test_progress.py checks them)."""
    return [ln for ln in stderr.splitlines() if not ln.startswith("zig builds ")]


def test_the_first_run_shows_its_build_into_the_cache_then_runs_quietly(tmp_path):
    """Into an empty cache, ``run`` (the Python flavor) names the FMUs, the platforms and
    the cache folder, then each step as it starts; the next run builds nothing and shows
    nothing (a run of 1 s)."""
    cache = tmp_path / "cache"
    args = ["run", "--no-plots", "--stop-time", "1", "--out", str(tmp_path / "run")]
    p = _cli(args, cache)
    assert "\r" not in p.stderr
    lines = _without_zig_notes(p.stderr)
    # a run's set: this machine's runtime alone (issue 48), in a folder of its own
    folder = cache / package_version() / "python-only-x86_64-linux-"
    head = ("building GliderPlant, GliderObserver, GliderController (python, FMI 2.0, for "
            f"x86_64-linux) into {folder}")  # fmt: skip
    assert lines[0].startswith(head), p.stderr
    assert lines[1:] == [
        "compiling the FMI 2.0 runtime for x86_64-linux (1 of 4)",
        "building GliderPlant.fmu python (2 of 4)",
        "building GliderObserver.fmu python (3 of 4)",
        "building GliderController.fmu python (4 of 4)",
    ]
    assert _cli(args, cache).stderr == ""  # built: nothing to wait for


def test_a_native_first_run_shows_each_compile_and_each_fmu_and_platform(tmp_path):
    cache = tmp_path / "cache"
    p = _cli(["run", "--flavor", "native", "--no-plots", "--stop-time", "1",
              "--out", str(tmp_path / "run")], cache)  # fmt: skip
    lines = _without_zig_notes(p.stderr)
    assert lines[0].startswith(
        "building GliderPlant, GliderObserver, GliderController (native, FMI 2.0, for "
        f"{HOST}) into {cache / package_version()}{os.sep}native-only-{HOST}-"
    ), p.stderr
    compiles = [ln for ln in lines if ln.startswith("compiling ")]
    assert len(compiles) == 9 and all(f".c for {HOST} (" in ln for ln in compiles), compiles
    assert lines[-3:] == [
        f"building GliderPlant.fmu native {HOST} (10 of 12)",
        f"building GliderObserver.fmu native {HOST} (11 of 12)",
        f"building GliderController.fmu native {HOST} (12 of 12)",
    ]
    assert [k for k, _ in _steps(lines)] == list(range(1, 13))


def test_quiet_shows_no_progress(tmp_path):
    """``--quiet``: the same first native run into an empty cache, and nothing on stderr."""
    p = _cli(["run", "--flavor", "native", "--no-plots", "--stop-time", "1", "--quiet",
              "--out", str(tmp_path / "run")], tmp_path / "cache")  # fmt: skip
    assert p.stderr == ""
    assert (tmp_path / "run" / "results.csv").is_file()
    p = _cli(["build", "-q", "--out", str(tmp_path / "fmus")], tmp_path / "cache")
    assert p.stderr == "" and p.stdout.count(".fmu") == 3


def test_a_build_on_a_terminal_draws_a_bar(tmp_path):
    text = _cli_on_a_terminal(["build", "--out", str(tmp_path / "fmus")], tmp_path / "cache")
    assert text.startswith("building GliderPlant, GliderObserver, GliderController (python"), text
    assert "build:" in text and "%|" in text and "4/4" in text, text
    assert "building GliderController.fmu python" in text
    assert "(1 of 4)" not in text  # a bar, not plain lines


def test_real_time_shows_the_wall_time_against_its_total(native_dir, tmp_path):
    """``run --real-time`` of 3 s: from 2 s on, the wall time against the run's 3 s, in
    lines (the last at the end); on a terminal, a bar."""
    args = ["run", "--flavor", "native", "--real-time", "--stop-time", "3", "--no-plots",
            "--out", str(tmp_path / "run")]  # fmt: skip
    p = _cli(args)
    lines = p.stderr.splitlines()
    assert lines, "no progress"
    assert all(re.fullmatch(r"run --real-time: \d s of 3 s \(t = \d\.\d / 3 s\)", ln)
               for ln in lines), lines  # fmt: skip
    assert lines[-1].endswith("(t = 3.0 / 3 s)") and "\r" not in p.stderr
    text = _cli_on_a_terminal(args)
    assert "run --real-time:" in text and "%|" in text and " of 3 s, t = " in text, text


def test_a_sweep_shows_its_workers_start_and_runs_done(native_dir, tmp_path):
    p = _cli(["sweep", "--param", "controller.K_c=4,6,8,10", "--flavor", "native",
              "--workers", "1", "--no-plots", "--out", str(tmp_path / "sweep")])  # fmt: skip
    lines = p.stderr.splitlines()
    assert lines[0] == "sweep: starting 1 local Dask worker", p.stderr
    done = [re.fullmatch(r"sweep: (\d) of 4 runs done, 0 failed, [\d.]+ runs/s", ln)
            for ln in lines[1:]]  # fmt: skip
    assert all(done) and done[-1][1] == "4", lines
    assert [int(m[1]) for m in done] == sorted(int(m[1]) for m in done)


def test_a_report_shows_each_step_as_it_starts(fmu_dir, tmp_path):
    out = tmp_path / "report"
    p = _cli(["report", "--roa-grid", "none", "--no-plots", "--out", str(out)])
    lines = p.stderr.splitlines()
    n = len(lines) - 1
    assert lines[0] == f"report: {n} steps into {out}", p.stderr
    assert _steps(lines[1:]) == [(k, n) for k in range(1, n + 1)]
    assert lines[1] == f"report: running fig2: open loop (1 of {n})"
    assert f"report: drawing fig11-20 ({n - 2} of {n})" in lines
    assert lines[-1] == f"report: drawing fig8 ({n} of {n})"
