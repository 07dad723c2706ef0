"""``glider-cosim host-env``: the environment a C or C++ FMI host needs to load our FMUs.

pythonfmu FMUs do not link libpython: their binary uses the interpreter of the host
process. A Python host (fmpy, libcosimpy) has one; a C/C++ host must preload libpython
and point Python at the packages the FMUs import (numpy, scipy, and ours when installed
in development mode).
"""

from __future__ import annotations

import os
import sys
import sysconfig
from pathlib import Path


class HostEnvError(RuntimeError):
    """This Python cannot serve a C host (e.g. it has no shared libpython)."""


def libpython() -> Path:
    """Path of the shared libpython of the running interpreter."""
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    for name in (sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LDLIBRARY")):
        if name and name.endswith((".so", ".dylib")) or (name and ".so." in name):
            p = Path(libdir) / name
            if p.exists():
                return p
    raise HostEnvError(
        f"no shared libpython found in {libdir!r}: this Python was built without "
        "--enable-shared, a C host cannot load pythonfmu FMUs with it"
    )


def host_env() -> dict[str, str]:
    """Variables for a C/C++ host: LD_PRELOAD (libpython), PYTHONHOME, PYTHONPATH."""
    import numpy
    import scipy

    # the FMUs carry their own packages (resources/); numpy and scipy come from here
    paths = [str(Path(m.__file__).resolve().parent.parent) for m in (numpy, scipy)]
    paths += [p for p in sys.path if p.endswith("site-packages")]
    seen: list[str] = []
    for p in paths:
        if p not in seen:
            seen.append(p)
    return {
        "LD_PRELOAD": str(libpython()),
        "PYTHONHOME": sys.base_prefix,
        "PYTHONPATH": os.pathsep.join(seen),
    }


def main() -> int:
    """Print ``export NAME=value`` lines for a shell."""
    for k, v in host_env().items():
        print(f"export {k}='{v}'")
    return 0
