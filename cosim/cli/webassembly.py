"""The command line's WebAssembly parts: ``run --flavor wasm`` and ``explore``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

from .parser import UsageError


def dispatch(args: argparse.Namespace, check_out_dir: Callable[[Path, str], None]) -> int | None:
    """``--flavor wasm`` on any command: the native FMI 3.0 FMUs (built and found as such),
    run as their WebAssembly components by the master (``args.run_wasm``; ``--fmi 2``
    with it is refused); ``explore``: its exit code. None: the command is not done."""
    args.run_wasm = getattr(args, "flavor", None) == "wasm"
    if args.run_wasm:
        if getattr(args, "fmi", None) == 2:
            raise UsageError("--flavor wasm runs FMI 3.0 components: expected --fmi 3 or none")
        args.flavor, args.fmi = "native", 3
    if args.run_wasm or "glider_cosim.master.wasm" in sys.modules:  # set for this command
        from ..master.wasm import use_components

        use_components(args.run_wasm)
    if args.command == "explore":
        return explore(args, check_out_dir)
    return None


def explore(args: argparse.Namespace, check_out_dir: Callable[[Path, str], None]) -> int:
    """``glider-cosim explore``: write the page (the native FMI 3 FMUs built if needed)."""
    from ..fmus.folders import prepare_fmus
    from ..runner.explore import write_page
    from ..scenarios.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    out = Path(args.out) if args.out is not None else Path("out") / f"{scenario.name}-explore"
    check_out_dir(out, "--out")
    folder = None if args.fmu_dir is None else Path(args.fmu_dir)
    fmus = prepare_fmus(folder, "native", 3, host_only=folder is None,
                        overwrite=getattr(args, "overwrite_fmus", False))  # fmt: skip
    page = write_page(out, scenario, fmus)
    print(f"wrote {page} (open this file in a browser; no server needed)")
    return 0
