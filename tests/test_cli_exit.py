"""The console script's exit: the interpreter's own (``sys.exit(main())``), so threads are
joined, ``atexit`` handlers run and the standard streams flushed as in any Python
program; a stdout that cannot be flushed is status 120, as the interpreter gives."""

from __future__ import annotations

import os
import subprocess
import sys

#: the console script as installed: its function called with this argv
CONSOLE = ("import sys; sys.argv[0] = 'glider-cosim'\n"
           "from glider_cosim.cli import console_main\nconsole_main()\n")  # fmt: skip


def _console(*argv: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", CONSOLE, *argv], timeout=120, **kwargs)


def test_the_console_script_exits_with_the_commands_code():
    ok = _console("cache", capture_output=True, text=True)
    assert ok.returncode == 0 and "glider-cosim" in ok.stdout, ok.stderr
    bad = _console("run", "no-such-scenario", "--no-plots", capture_output=True, text=True)
    assert bad.returncode == 2, bad.stderr
    assert "Traceback" not in bad.stderr
    line = bad.stderr.splitlines()[-1]  # after the build's progress lines: one line
    assert line.startswith("glider-cosim run: error: ") and "no-such-scenario" in line


def test_a_stdout_that_cannot_be_flushed_is_status_120_as_the_interpreter_gives():
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}  # a pipe: buffered
    read, write = os.pipe()
    os.close(read)  # the reader is gone: flushing stdout fails (EPIPE)
    try:
        ours = _console("cache", stdout=write, stderr=subprocess.PIPE, env=env)
        plain = subprocess.run([sys.executable, "-c", "print('x' * 100)"], stdout=write,
                               stderr=subprocess.PIPE, timeout=60, env=env)  # fmt: skip
    finally:
        os.close(write)
    assert ours.returncode == plain.returncode == 120
