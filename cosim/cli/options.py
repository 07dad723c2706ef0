"""The options several commands share, each declared once here: the FMU folder's
(``--fmu-dir``, ``--flavor``, ``--fmi``, ``--overwrite-fmus``), the scenario, ``--out``,
the Dask ones, ``--no-plots``, ``--format``, ``--json``. A command's own wording of a
help text is passed in; the flag, its type and default are here."""

from __future__ import annotations

from typing import Any

from ..fmus.options import FLAVORS, FMI_VERSIONS, WASM_FLAVOR


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


def add_fmu_dir(parser: Any, help: str) -> None:  # noqa: A002
    """``--fmu-dir``: a folder of our FMUs (default: the per-user cache)."""
    parser.add_argument("--fmu-dir", default=None, help=help)


def add_fmu_options(parser: Any, fmi: bool = False, wasm: bool = False) -> None:
    """``--fmu-dir`` and ``--flavor`` on a command that runs our FMUs (and ``--fmi``
    with ``fmi``; ``--flavor wasm`` with ``wasm``)."""
    add_fmu_dir(
        parser,
        "FMU folder, built if missing or stale in the flavor it holds; one that does not "
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


def add_scenario(parser: Any, help: str = "scenario; default: default", **kwargs: Any) -> None:  # noqa: A002
    """The scenario a command runs: a TOML file or a shipped name (optional unless
    ``nargs`` says otherwise)."""
    kwargs.setdefault("nargs", "?")
    kwargs.setdefault("default", None)
    parser.add_argument("scenario", help=help, **kwargs)


def add_out(parser: Any, help: str, default: str | None = None, **kwargs: Any) -> None:  # noqa: A002
    """``--out``: the command's output folder or file."""
    parser.add_argument("--out", default=default, help=help, **kwargs)


def add_dask(parser: Any, workers: str) -> None:
    """``--workers`` (its help: ``workers``) and ``--scheduler``."""
    parser.add_argument("--workers", type=int, default=2, help=workers)
    parser.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")


def add_no_plots(parser: Any, help: str) -> None:  # noqa: A002
    """``--no-plots``: skip what the command draws."""
    parser.add_argument("--no-plots", action="store_true", help=help)


def add_format(parser: Any, help: str) -> None:  # noqa: A002
    """``--format``: csv (text) or parquet (binary; needs pyarrow)."""
    parser.add_argument("--format", choices=("csv", "parquet"), default="csv", help=help)


def add_json(parser: Any, help: str) -> None:  # noqa: A002
    """``--json``: one JSON object on stdout instead of the text."""
    parser.add_argument("--json", action="store_true", help=help)
