"""``glider-cosim compare``: its run, once its arguments are parsed (the study is
:mod:`glider_cosim.studies.compare`, imported when the command runs)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path


def run(args: argparse.Namespace, check_out_dir: Callable[[Path, str], None]) -> int:
    """Check the scenario and ``--out`` (one line each, before anything is run), compare,
    print the summary; 0 when the runs complete, whatever the comparison says."""
    from ..scenarios.scenario import load_scenario
    from ..studies.compare import compare, default_out, describe, swapped_component

    swapped_component(load_scenario(args.scenario))
    out = Path(args.out) if args.out is not None else default_out(args.scenario)
    check_out_dir(out, "--out")
    print(describe(compare(args.scenario, out, args.fmu_dir)))
    return 0
