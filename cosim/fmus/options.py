"""The command-line options that pick our FMUs (``--fmu-dir``, ``--flavor``, ``--fmi``)
and their choices; light (argparse only), for the command line's parser."""

from __future__ import annotations

from typing import Any

#: the flavors of our FMUs: the Python reference (default) and the native C99 build
FLAVORS = ("python", "native")
#: what ``run --flavor`` also takes: the native FMI 3.0 FMUs' WebAssembly components,
#: run by wasmtime (FMI-LS-WASM)
WASM_FLAVOR = "wasm"
#: the FMI versions we build (``--fmi``)
FMI_VERSIONS = (2, 3)


def add_overwrite_option(parser: Any, folder: str = "--fmu-dir") -> None:
    """``--overwrite-fmus``: let a build replace, in the FMU folder ``folder`` names, what
    glider-cosim did not build there (see :mod:`glider_cosim.fmus.record`)."""
    parser.add_argument(
        "--overwrite-fmus",
        action="store_true",
        help=f"replace what {folder} holds under our FMUs' names (GliderPlant.fmu, ...) even "
        "if glider-cosim did not build it there, it changed since or it is another flavor or "
        "FMI version (default: off: such a folder is refused, naming the file; its record of "
        "what glider-cosim built is .glider-cosim-fmus.json)",
    )


def add_fmu_options(parser: Any, fmi: bool = False, wasm: bool = False) -> None:
    """``--fmu-dir`` and ``--flavor`` on a command that runs our FMUs (and ``--fmi``
    with ``fmi``; ``--flavor wasm`` with ``wasm``)."""
    parser.add_argument(
        "--fmu-dir",
        default=None,
        help="FMU folder, built if missing or stale in the flavor it holds; one that does not "
        "exist gets a fresh set, with a note (default: the per-user cache, e.g. "
        "~/.cache/glider-cosim, built from the installed sources)",
    )
    parser.add_argument(
        "--flavor",
        choices=(*FLAVORS, WASM_FLAVOR) if wasm else FLAVORS,
        default=None,
        help="which FMUs: the Python reference or the native C99 build"
        + (
            ", or wasm: the native FMI 3.0 FMUs' WebAssembly components under wasmtime"
            if wasm
            else ""
        )
        + " (default: the flavor the FMU folder holds, python if it is empty)",
    )
    add_overwrite_option(parser)
    if fmi:
        parser.add_argument(
            "--fmi",
            type=int,
            choices=FMI_VERSIONS,
            default=None,
            help="FMI version of our FMUs (default: the one the FMU folder holds, 2 if it is "
            "empty; FMI 3 FMUs are built in the per-user cache, or in --fmu-dir)",
        )
