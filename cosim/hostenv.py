"""``glider-cosim host-env``: the environment a C or C++ FMI host needs to load our FMUs.

pythonfmu's FMU binaries do not link libpython: they call the Python C API of whatever
interpreter the host process has. A Python host (fmpy, libcosimpy) has one, with its own
``sys.path``. A C or C++ host (a hand-written host, OMSimulator, Simulink, Dymola) has
none: ``dlopen`` of the FMU binary fails with ``undefined symbol: _Py_NoneStruct`` (or
another C-API symbol) unless libpython is preloaded, and the embedded interpreter must
then find the packages the FMUs import (numpy, scipy; the FMUs carry our own packages in
their ``resources/``).

:func:`host_env` returns, for the running interpreter:

``LD_PRELOAD``
    the shared libpython (``sysconfig``: ``INSTSONAME`` or ``LDLIBRARY`` in ``LIBDIR``),
    in front of any ``LD_PRELOAD`` already set;
``PYTHONPATH``
    the site-packages folders holding numpy and scipy, and the other site-packages of
    this interpreter (its pure and platform library folders, a virtual environment's
    included), then any ``PYTHONPATH`` already set;
``PYTHONHOME``
    only if needed: when this interpreter's base prefix differs from the prefix compiled
    into libpython (a relocated install: an embedded interpreter would look for its
    standard library in the wrong place), or when the variable is already set.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import shlex
import sys
import sysconfig
from collections.abc import Sequence
from pathlib import Path

#: packages the FMUs import from the host's environment
FMU_IMPORTS = ("numpy", "scipy")


class HostEnvError(OSError):
    """This Python cannot serve a C host (no shared libpython, a package missing)."""


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
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    names = [sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LDLIBRARY")]
    for name in names:
        if name and (name.endswith((".so", ".dylib")) or ".so." in name):
            for folder in (libdir, sysconfig.get_config_var("LIBPL") or ""):
                p = Path(folder) / name
                if p.is_file():
                    return p
    raise HostEnvError(
        f"libpython: no shared library {names[0] or names[1]!r} in {libdir!r}: this Python "
        "was built without --enable-shared, and a C host cannot load pythonfmu FMUs with it"
    )


def _package_root(module: str) -> str:
    """The folder a package is imported from (its site-packages)."""
    spec = importlib.util.find_spec(module)
    if spec is None or not spec.origin:
        raise HostEnvError(f"PYTHONPATH: the FMUs need '{module}', which this Python lacks")
    return str(Path(spec.origin).resolve().parent.parent)


def _python_home_needed() -> bool:
    compiled = sysconfig.get_config_var("prefix") or ""
    return "PYTHONHOME" in os.environ or (
        os.path.realpath(compiled) != os.path.realpath(sys.base_prefix)
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
        No shared libpython, or numpy or scipy missing.
    """
    paths = [_package_root(m) for m in FMU_IMPORTS]
    scheme = sysconfig.get_paths()
    paths += [scheme["purelib"], scheme["platlib"]]
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
        description="Print the environment a C/C++ FMI host needs for our FMUs, e.g. "
        'eval "$(glider-cosim host-env)".',
    )
    parser.parse_args(list(argv) if argv is not None else [])
    try:
        env = host_env()
    except HostEnvError as err:
        print(f"glider-cosim: error: {err}", file=sys.stderr)
        return 2
    for name, value in env.items():
        print(f"export {name}={shlex.quote(value)}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main(sys.argv[1:]))
