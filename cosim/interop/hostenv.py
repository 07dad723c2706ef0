"""``glider-cosim host-env``: the environment a C or C++ FMI host on another machine needs.

On the machine that built them, our FMUs need no setup: their runtime
(:mod:`glider_fmi.compile`) uses the host's Python if it has one and otherwise loads and
starts the Python recorded at build time (``resources/glider_fmi_python.cfg``). On
another machine, with another Python installation, either point the runtime at a
configuration written there (``glider-cosim host-env --config > py.cfg`` and
``GLIDER_FMI_PYTHON_CONFIG=$PWD/py.cfg``), or set the environment this module prints: with
libpython preloaded the runtime finds Python in the process and starts it with these
variables.

:func:`host_env` returns, for the running interpreter:

``LD_PRELOAD``
    the shared libpython (``sysconfig``: ``INSTSONAME`` or ``LDLIBRARY`` in ``LIBDIR``),
    in front of any ``LD_PRELOAD`` already set;
``PYTHONPATH``
    the site-packages folders of this interpreter (its pure and platform library
    folders, a virtual environment's included), then any ``PYTHONPATH`` already set (the
    FMUs bundle what they import; this keeps the host's own packages importable);
``PYTHONHOME``
    where it is needed: when this interpreter's base prefix differs from the prefix
    compiled into libpython (a relocated install), when the first ``python3`` on
    ``PATH`` is another installation (an embedded interpreter derives its prefix from
    it, e.g. ``/usr`` from Debian's, and then misses the standard library:
    ``No module named 'math'``), or when the variable is already set.
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import sys
import sysconfig
from collections.abc import Sequence
from pathlib import Path

from glider_fmi import compile as runtime

from ..inputs.text import one_line, prefix


class HostEnvError(OSError):
    """This Python cannot serve a C host (no shared libpython)."""


def libpython() -> Path:
    """Path of the running interpreter's shared libpython.

    Returns
    -------
    Path
        E.g. ``.../lib/libpython3.11.so.1.0``.

    Raises
    ------
    HostEnvError
        The interpreter was built without ``--enable-shared`` (no shared library).
    """
    try:
        return runtime.libpython()
    except runtime.RuntimeBuildError as err:
        raise HostEnvError(str(err)) from None


def _python_home_needed() -> bool:
    compiled = sysconfig.get_config_var("prefix") or ""
    first = shutil.which("python3")
    first_prefix = Path(os.path.realpath(first)).parent.parent if first else None
    base = Path(os.path.realpath(sys.base_prefix))
    return (
        "PYTHONHOME" in os.environ
        or Path(os.path.realpath(compiled)) != base
        or first_prefix != base
    )


def host_env() -> dict[str, str]:
    """Environment variables a C/C++ host needs to load our pythonfmu FMUs.

    Returns
    -------
    dict of str to str
        ``LD_PRELOAD``, ``PYTHONPATH`` and, if needed, ``PYTHONHOME`` (see the module
        docstring); existing ``LD_PRELOAD`` and ``PYTHONPATH`` entries are kept after
        ours.

    Raises
    ------
    HostEnvError
        No shared libpython.
    """
    scheme = sysconfig.get_paths()
    paths = [scheme["purelib"], scheme["platlib"]]
    paths += [p for p in sys.path if p.endswith(("site-packages", "dist-packages"))]
    paths += [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    preload = [str(libpython())]
    preload += [p for p in os.environ.get("LD_PRELOAD", "").split() if p not in preload]
    env = {
        "LD_PRELOAD": " ".join(preload),
        "PYTHONPATH": os.pathsep.join(dict.fromkeys(p for p in paths if Path(p).is_dir())),
    }
    if _python_home_needed():
        env["PYTHONHOME"] = os.environ.get("PYTHONHOME", sys.base_prefix)
    return env


def main(argv: Sequence[str] | None = None) -> int:
    """Print ``export NAME=value`` lines for a POSIX shell (``glider-cosim host-env``).

    Parameters
    ----------
    argv : sequence of str, optional
        Command-line arguments after ``host-env`` (none are taken besides ``-h``).

    Returns
    -------
    int
        0, or 2 with a one-line message on stderr if the environment cannot be given.
    """
    parser = argparse.ArgumentParser(
        prog="glider-cosim host-env",
        description="Print the environment a C/C++ FMI host on another machine needs for "
        'our FMUs, e.g. eval "$(glider-cosim host-env)". On the machine that built the FMUs '
        "no setup is needed.",
    )
    parser.add_argument(
        "--config",
        action="store_true",
        help="print instead the FMU runtime's Python configuration for this interpreter "
        f"(save it and point ${runtime.PYTHON_CONFIG_ENV} at the file)",
    )
    args = parser.parse_args(list(argv) if argv is not None else [])
    if args.config:
        print(runtime.python_config(), end="")
        return 0
    try:
        env = host_env()
    except HostEnvError as err:
        print(f"{prefix('error', 'host-env')}{one_line(err)}", file=sys.stderr)
        return 2
    for name, value in env.items():
        print(f"export {name}={shlex.quote(value)}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main(sys.argv[1:]))
