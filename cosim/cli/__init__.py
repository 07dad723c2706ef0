"""glider-cosim's command line: build the FMUs, run scenarios, analyse, sweep, verify, report.

``glider-cosim COMMAND --help`` shows every option with its default. :func:`main` takes
an argument list and returns the exit code; :func:`console_main` is the console script.
"""

from .main import console_main, main
from .parser import UsageError, build_parser

__all__ = ["UsageError", "build_parser", "console_main", "main"]
