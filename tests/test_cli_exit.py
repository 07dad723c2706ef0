"""The console script's exit (``glider_cosim.cli.main.exit_now``): what the interpreter's
exit does that matters (threads joined, ``atexit`` handlers, the standard streams
flushed, status 120 for a stdout that cannot be flushed), without tearing down every
module (issue 31: 50-90 ms of each command)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import atexit, sys, threading, time
    from pathlib import Path
    from glider_cosim.cli.main import exit_now

    out = Path(sys.argv[1])

    def late():
        time.sleep(0.3)
        (out / "thread").write_text("joined")

    threading.Thread(target=late).start()  # not a daemon: joined before the exit
    atexit.register(lambda: (out / "atexit").write_text("ran"))
    print("x" * 100)  # buffered (a pipe): flushed by the exit
    exit_now(int(sys.argv[2]))
""")


def test_exit_now_joins_threads_runs_atexit_and_flushes(tmp_path):
    p = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path), "3"], capture_output=True,
                       text=True, timeout=60)  # fmt: skip
    assert (p.returncode, p.stdout, p.stderr) == (3, "x" * 100 + "\n", "")
    assert (tmp_path / "thread").read_text() == "joined"
    assert (tmp_path / "atexit").read_text() == "ran"


def test_a_stdout_that_cannot_be_flushed_is_status_120_as_the_interpreter_gives(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}  # a pipe: buffered
    read, write = os.pipe()
    os.close(read)  # the reader is gone: flushing stdout fails (EPIPE)
    try:
        ours = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path), "0"], stdout=write,
                              stderr=subprocess.PIPE, timeout=60, env=env)  # fmt: skip
        plain = subprocess.run([sys.executable, "-c", "print('x' * 100)"], stdout=write,
                               stderr=subprocess.PIPE, timeout=60, env=env)  # fmt: skip
    finally:
        os.close(write)
    assert ours.returncode == plain.returncode == 120
    assert (tmp_path / "atexit").read_text() == "ran"


def test_the_console_script_exits_through_exit_now():
    import importlib
    import inspect
    import tomllib
    from pathlib import Path

    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    script = tomllib.loads(pyproject.read_text())["project"]["scripts"]["glider-cosim"]
    module, _, func = script.partition(":")
    source = inspect.getsource(getattr(importlib.import_module(module), func))
    assert "exit_now(main())" in source
    p = subprocess.run([sys.executable, "-m", "glider_cosim.cli", "cache"], capture_output=True,
                       text=True, timeout=60)  # fmt: skip
    assert p.returncode == 0 and "glider-cosim" in p.stdout, p.stderr
