"""The console script: parse, run the command, turn every error into one line and an exit code.

Exit codes: 0 success, 1 the run stopped or failed in an FMU (results up to the failure
are written), 2 bad input (arguments, scenario, SSP, FMU files; one line), 130
interrupted by Ctrl-C, 143 terminated by SIGTERM (results so far are written), 3 the
command needs an optional extra that is not installed (one line with the ``pip install``
that brings it: :mod:`glider_cosim.extras`).
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
import warnings
from collections.abc import Sequence
from typing import NoReturn

from ..extras import MissingExtra, check_command
from ..inputs.text import one_line, prefix
from ..master.errors import Interrupted, MasterError, SystemSpecError
from ..scenarios.fields import ScenarioError
from .parser import _plain, _version, build_parser


def _terminate(signum: int, frame: object) -> None:
    raise Interrupted(signum)


class _NoteHandler(logging.Handler):
    """Warnings of our modules as one-line notes on the current ``sys.stderr``."""

    def emit(self, record: logging.LogRecord) -> None:
        sys.stderr.write(f"{prefix('note')}{one_line(record.getMessage())}\n")


def _notes_to_stderr() -> None:
    """Warnings of our modules (e.g. a skipped optional connection) as one-line notes."""
    logger = logging.getLogger("glider_cosim")
    if not any(isinstance(h, _NoteHandler) for h in logger.handlers):
        handler = _NoteHandler(logging.WARNING)
        logger.addHandler(handler)


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"{prefix('warning')}{message}", file=sys.stderr if file is None else file)


def _matplotlib_cache() -> None:
    """matplotlib's font cache in glider-cosim's per-user cache, beside the built FMUs
    (``<cache>/<version>/matplotlib``, :func:`~glider_cosim.fmus.files.cache_root`;
    matplotlib creates it when it first draws), not ``~/.cache/matplotlib``: a command
    writes nothing outside its output folder and our cache (unless the user points
    ``MPLCONFIGDIR`` somewhere). Built once: rebuilt each time, it cost 0.2 s a command.
    matplotlib draws every PNG (the run's, the sweep's, the report's).
    Where it cannot be written, the process's temporary folder holds it."""
    if "MPLCONFIGDIR" in os.environ or "matplotlib" in sys.modules:
        return
    from ..fmus.files import cache_root, package_version

    folder = cache_root() / package_version() / "matplotlib"
    existing = folder
    while not existing.exists() and existing.parent != existing:
        existing = existing.parent
    if not (existing.is_dir() and os.access(existing, os.W_OK | os.X_OK)):
        from ..inputs.tempdirs import new_temp_dir

        folder = new_temp_dir("matplotlib_")
    os.environ["MPLCONFIGDIR"] = str(folder)


#: the first command to try, named by a bare ``glider-cosim``
FIRST_COMMAND = "glider-cosim run"


def overview(parser: argparse.ArgumentParser) -> str:
    """What a bare ``glider-cosim`` prints: every command with its one-line help, and the
    first one to try."""
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    width = max(len(c.dest) for c in sub._choices_actions)
    lines = [f"usage: glider-cosim COMMAND [options]  (glider-cosim {_version()})", "",
             "commands:"]  # fmt: skip
    lines += [f"  {c.dest:{width}s}  {_plain(c.help or '')}" for c in sub._choices_actions]
    lines += [
        "",
        f"First try: {FIRST_COMMAND}   (builds the FMUs once, runs the default scenario,",
        "writes out/default/). Each command's options: glider-cosim COMMAND --help",
    ]
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``glider-cosim`` console script (returns the exit code; notes and
    warnings one line each)."""
    given = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(given[0] if given and not given[0].startswith("-") else None)
    args = parser.parse_args(argv)
    if args.command is None:  # a bare ``glider-cosim``: the commands and the first to try
        sys.stdout.write(overview(parser))
        return 0
    args.argv = given  # for "resume with: ..."
    from .. import progress

    was_quiet = progress.is_quiet()  # --quiet for this command only (main runs in tests too)
    progress.set_quiet(getattr(args, "quiet", False) or getattr(args, "no_progress", False))
    _notes_to_stderr()
    _matplotlib_cache()
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            return _main(args)
    finally:
        progress.set_quiet(was_quiet)


def _main(args: argparse.Namespace) -> int:
    command = getattr(args, "command", None)
    from .commands import dispatch  # after parsing: --help imports none of the commands

    error = prefix("error", command)
    old_term = None
    if threading.current_thread() is threading.main_thread():
        old_term = signal.signal(signal.SIGTERM, _terminate)  # cleaned up like Ctrl-C
    try:
        check_command(args)  # an optional extra it needs: before anything is built
        code = dispatch(args)
    except MissingExtra as err:
        print(f"{error}{one_line(err)}", file=sys.stderr)
        code = 3
    except (ScenarioError, SystemSpecError, ValueError) as err:
        print(f"{error}{one_line(err)}", file=sys.stderr)
        code = 2
    except MasterError as err:
        print(f"{error}{one_line(err)}", file=sys.stderr)
        code = 1
    except KeyboardInterrupt as err:
        kept = getattr(err, "kept", "")  # where the results are, how to go on
        kept = f": {kept}" if kept else ""
        if isinstance(err, Interrupted) and err.signum == signal.SIGTERM:
            print(f"{error}terminated (SIGTERM); results so far are written{kept}",
                  file=sys.stderr)  # fmt: skip
            code = 143
        else:
            print(f"{error}interrupted; results so far are written{kept}", file=sys.stderr)
            code = 130
    except OSError as err:
        print(f"{error}{one_line(err)}", file=sys.stderr)
        code = 2
    except RecursionError:
        print(f"{error}input nested too deeply", file=sys.stderr)
        code = 2
    finally:
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
    return code


def console_main() -> NoReturn:
    """Console script: run :func:`main` and exit with its code."""
    sys.exit(main())


if __name__ == "__main__":
    console_main()
