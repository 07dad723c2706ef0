"""Progress of every wait over two seconds (issue 45): a bar on a terminal, plain lines in a
pipe, a file or CI (one per step, no carriage return), nothing with ``--quiet``."""

from __future__ import annotations

import fcntl
import io
import os
import pty
import select
import struct
import subprocess
import sys
import termios

import pytest

from glider_cosim import progress
from glider_cosim.cli.parser import build_parser
from glider_cosim.fmus import objects
from glider_fmi import toolchain


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.fixture(autouse=True)
def no_ci(monkeypatch):
    for v in progress.CI_VARIABLES:
        monkeypatch.delenv(v, raising=False)
    monkeypatch.setenv("TERM", "xterm")
    progress.set_quiet(False)
    yield
    progress.set_quiet(False)


def test_a_bar_on_a_terminal_lines_elsewhere_nothing_when_quiet(monkeypatch):
    assert progress.mode(_Tty()) == "bar"
    assert progress.mode(io.StringIO()) == "lines"  # a pipe or a file
    monkeypatch.setenv("CI", "true")
    assert progress.mode(_Tty()) == "lines"  # CI logs get plain lines
    monkeypatch.delenv("CI")
    monkeypatch.setenv("TERM", "dumb")
    assert progress.mode(_Tty()) == "lines"
    progress.set_quiet(True)
    assert progress.mode(_Tty()) == progress.mode(io.StringIO()) == "off"


def test_steps_as_plain_lines():
    out = io.StringIO()
    with progress.Progress(3, "build", "building 3 FMUs into /x", stream=out) as bar:
        bar.step("building GliderPlant.fmu native x86_64-linux")
        bar.note("zig builds its C runtime for x86_64-windows once into ~/.cache/zig")
        bar.step("building GliderObserver.fmu native x86_64-linux")
        bar.step("building GliderController.fmu native x86_64-linux")
    assert out.getvalue().splitlines() == [
        "building 3 FMUs into /x",
        "building GliderPlant.fmu native x86_64-linux (1 of 3)",
        "zig builds its C runtime for x86_64-windows once into ~/.cache/zig",
        "building GliderObserver.fmu native x86_64-linux (2 of 3)",
        "building GliderController.fmu native x86_64-linux (3 of 3)",
    ]
    assert "\r" not in out.getvalue()


def test_quiet_shows_nothing_and_silences_what_runs_inside():
    out = io.StringIO()
    progress.set_quiet(True)
    with progress.Progress(2, "build", "building", stream=out) as bar:
        bar.step("one")
        bar.note("a note")
    progress.say("sweep: starting 2 local Dask workers", out)
    progress.set_quiet(False)
    with progress.Progress(2, "report", "report", stream=out, quiet=True):
        inner = progress.RunProgress(_Rec(), rows=256, stop_time=5.12, stream=out)
        assert inner.mode == "off"  # a report's runs show no progress of their own
    assert out.getvalue() == ""


def test_a_task_inside_another_stays_silent():
    out = io.StringIO()
    with progress.Progress(1, "report", stream=out) as outer:
        outer.step("report: running fig2: open loop")
        with progress.Progress(1, "build", "building", stream=out) as inner:
            inner.step("building GliderPlant.fmu python")
        progress.say("sweep: drawing the plots", out)
    assert out.getvalue() == "report: running fig2: open loop (1 of 1)\n"
    progress.say("sweep: drawing the plots", out)  # the outer task has ended
    assert out.getvalue().endswith("\nsweep: drawing the plots\n")


class _Rec:
    def __init__(self):
        self.rows, self.closed = [], False

    def start(self, columns):
        self.columns = columns

    def row(self, values):
        self.rows.append(values)

    def close(self):
        self.closed = True


def _run(rec: progress.RunProgress, rows: int) -> None:
    rec.start(["time"])
    for k in range(rows):
        rec.row([k * 0.02])
    rec.close()


def test_a_long_run_as_plain_lines(monkeypatch):
    out, inner = io.StringIO(), _Rec()
    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)
    monkeypatch.setattr(progress, "LINE_EVERY_S", 0.0)
    _run(progress.RunProgress(inner, rows=256, stop_time=5.12, stream=out), 256)
    assert len(inner.rows) == 256 and inner.closed
    lines = out.getvalue().splitlines()
    assert len(lines) == 5 and "\r" not in out.getvalue()  # rows 64, 128, 192, 256, the end
    assert lines[0].startswith("run: t = 1.3 / 5.12 s simulated, 0 s elapsed, about ")
    assert lines[-1] == "run: t = 5.1 / 5.12 s simulated in 0 s"


def test_a_real_time_run_shows_its_wall_time_against_the_total(monkeypatch):
    out = io.StringIO()
    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)
    monkeypatch.setattr(progress, "LINE_EVERY_S", 1e9)  # the first line and the last
    _run(progress.RunProgress(_Rec(), rows=128, stop_time=60, real_time=30.0, stream=out), 64)
    assert out.getvalue().splitlines() == [
        "run --real-time: 0 s of 30 s (t = 0.5 / 60 s)",  # paced rows: the clock each row
        "run --real-time: 0 s of 30 s (t = 30.0 / 60 s)",
    ]


def test_the_c_loops_blocks_are_counted(monkeypatch):
    """A native run hands its rows over in blocks (``rows_block``): they count too, and a
    recorder without blocks gets none offered."""
    out, seen = io.StringIO(), []

    class Blocks(_Rec):
        def rows_block(self, values, nrows, ncol):
            seen.append(nrows)

    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)
    monkeypatch.setattr(progress, "LINE_EVERY_S", 1e9)
    rec = progress.RunProgress(Blocks(), rows=1000, stop_time=20.0, stream=out)
    rec.start(["time"])
    rec.rows_block([0.0] * 500, 500, 1)
    rec.close()
    assert seen == [500] and out.getvalue().splitlines()[0].startswith("run: t = 10.0 / 20 s")
    assert getattr(progress.RunProgress(_Rec(), 10, 1.0, stream=out), "rows_block", None) is None


def test_a_short_run_shows_nothing():
    out = io.StringIO()
    _run(progress.RunProgress(_Rec(), rows=100, stop_time=2.0, stream=out), 100)
    assert out.getvalue() == ""


def test_sweep_lines():
    out = io.StringIO()
    callback, bar = progress.sweep_progress(out)
    with bar:
        callback(3, 4, 0, 1.0)
        callback(4, 4, 1, 2.0)
    assert out.getvalue().splitlines() == [
        "sweep: 3 of 4 runs done, 0 failed, 3.0 runs/s",
        "sweep: 4 of 4 runs done, 1 failed, 2.0 runs/s",
    ]


def _on_a_terminal(code: str, rows: int = 24, columns: int = 80) -> str:
    """What ``code``, run in a new interpreter whose stderr is a terminal (a pty of 80
    columns, or the size given), writes there."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", rows, columns, 0, 0))
    env = {k: v for k, v in os.environ.items() if k not in progress.CI_VARIABLES}
    env["TERM"] = "xterm"
    proc = subprocess.Popen([sys.executable, "-c", code], stderr=slave, stdout=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, env=env)  # fmt: skip
    os.close(slave)
    chunks = []
    while True:
        ready, _, _ = select.select([master], [], [], 30)
        if not ready:
            break
        try:
            data = os.read(master, 4096)
        except OSError:  # the child closed its end
            break
        if not data:
            break
        chunks.append(data)
    proc.wait(timeout=30)
    os.close(master)
    assert proc.returncode == 0, b"".join(chunks).decode(errors="replace")[-2000:]
    return b"".join(chunks).decode(errors="replace")


def test_a_terminal_gets_a_bar():
    text = _on_a_terminal(
        "from glider_cosim import progress\n"
        "with progress.Progress(2, 'build', 'building 2 FMUs') as bar:\n"
        "    bar.step('building GliderPlant.fmu python')\n"
        "    bar.step('building GliderObserver.fmu python')\n"
    )
    assert text.startswith("building 2 FMUs\r\n")  # the header, then the bar in place
    assert "build:  50%|" in text and "1/2" in text and "building GliderObserver.fmu python" in text
    assert "build: 100%|" in text and "2/2" in text
    assert "\r" in text.removeprefix("building 2 FMUs\r\n")  # redrawn in place, not new lines
    assert "(1 of 2)" not in text  # no plain lines


def test_a_terminal_of_size_0x0_gets_plain_lines():
    """``script(1)`` and some CI ptys report 0 rows and 0 columns: tqdm would draw
    nothing there, so the steps and a run's progress come as plain lines."""
    text = _on_a_terminal(
        "from glider_cosim import progress\n"
        "with progress.Progress(2, 'build', 'building 2 FMUs') as bar:\n"
        "    bar.step('building GliderPlant.fmu python')\n"
        "    bar.step('building GliderObserver.fmu python')\n"
        "progress.SHOW_AFTER_S = 0.0\n"
        "class R:\n"
        "    def start(self, c): pass\n"
        "    def row(self, v): pass\n"
        "    def close(self): pass\n"
        "rec = progress.RunProgress(R(), rows=256, stop_time=5.12)\n"
        "rec.start(['time'])\n"
        "for k in range(256): rec.row([k])\n"
        "rec.close()\n",
        rows=0,
        columns=0,
    )
    lines = text.replace("\r\n", "\n").splitlines()
    assert lines[:3] == [
        "building 2 FMUs",
        "building GliderPlant.fmu python (1 of 2)",
        "building GliderObserver.fmu python (2 of 2)",
    ]
    assert lines[3].startswith("run: t = ") and lines[-1].startswith("run: t = 5.1 / 5.12 s")
    assert "%|" not in text


def test_a_run_on_a_terminal_gets_a_bar_cleared_at_the_end():
    text = _on_a_terminal(
        "from glider_cosim import progress\n"
        "progress.SHOW_AFTER_S = 0.0\n"
        "class R:\n"
        "    def start(self, c): pass\n"
        "    def row(self, v): pass\n"
        "    def close(self): pass\n"
        "rec = progress.RunProgress(R(), rows=256, stop_time=5.12, real_time=5.12)\n"
        "rec.start(['time'])\n"
        "for k in range(256): rec.row([k])\n"
        "rec.close()\n"
    )
    assert "run --real-time:" in text and "%|" in text and "of 5 s, t = " in text
    assert "\n" not in text.replace("\r\n", "")  # one line, redrawn, then cleared


def test_zig_first_build_named_until_its_cache_holds_the_target(tmp_path, monkeypatch):
    """zig's one-time build of a platform's C runtime is named with its cache and the wait
    until the cache holds it: mingw-w64's ``libmingw32.lib``, a glibc ``libc.so.6`` stub
    of the platform's architecture."""
    monkeypatch.setenv("ZIG_GLOBAL_CACHE_DIR", str(tmp_path / "zig"))
    zig = toolchain.Compiler("zig", ("zig", "cc"), frozenset(toolchain.PLATFORMS), "ziglang")
    gcc = toolchain.Compiler("gcc", ("gcc",), frozenset({"x86_64-linux"}), "gcc")

    def note(key, compiler=zig):
        return objects.zig_first_note(objects.Target(key, toolchain.PLATFORMS[key], compiler))

    where = str(tmp_path / "zig")
    assert note("x86_64-windows") == (
        f"zig builds its C runtime (mingw-w64) for x86_64-windows once into {where} (about 2 min)"
    )
    assert note("aarch64-linux") == (
        f"zig builds its glibc stubs for aarch64-linux once into {where} (about 5 s)"
    )
    assert note("x86_64-linux", gcc) is None  # not zig's to build
    assert note("aarch64-darwin") is None  # nothing to wait for
    (tmp_path / "zig" / "o" / "a1").mkdir(parents=True)
    (tmp_path / "zig" / "o" / "a1" / "libmingw32.lib").write_bytes(b"!<arch>\n")
    elf = bytearray(64)
    elf[:4], elf[18:20] = b"\x7fELF", (62).to_bytes(2, "little")  # EM_X86_64
    (tmp_path / "zig" / "o" / "b2").mkdir()
    (tmp_path / "zig" / "o" / "b2" / "libc.so.6").write_bytes(bytes(elf))
    assert note("x86_64-windows") is None
    assert note("x86_64-linux") is None
    assert note("aarch64-linux") is not None  # an x86_64 stub is not aarch64's


def test_zig_cache_default_ignores_our_own_cache_variable(monkeypatch, tmp_path):
    monkeypatch.delenv("ZIG_GLOBAL_CACHE_DIR", raising=False)
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path / "ours"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert objects.zig_cache() == tmp_path / "xdg" / "zig"


def test_every_command_takes_quiet_with_its_default_in_help():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, command in sub.choices.items():
        quiet = next((a for a in command._actions if "--quiet" in a.option_strings), None)
        assert quiet is not None, f"{name} has no --quiet"
        assert quiet.option_strings == ["-q", "--quiet"] and quiet.default is False
        assert "default: off" in quiet.help and "plain lines" in quiet.help, name
    args = parser.parse_args(["run", "--quiet"])
    assert args.quiet is True


def test_quiet_holds_for_its_command_only(capsys):
    from glider_cosim.cli.main import main

    assert main(["scenarios", "--quiet"]) == 0
    assert "default" in capsys.readouterr().out
    assert not progress.is_quiet()  # the next command (or test) in this process shows again
