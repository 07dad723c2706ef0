"""Each component's reference case: its FMU run alone on the ``reference_input.csv`` of
its folder, with the parameters of its ``component.toml`` ``[reference]``, gives its
``reference_output.csv`` (data in the component's folder, named by the component registry).

``python -m glider_cosim.verify.reference`` runs every component's case on our FMUs and
compares (exit 1 if one differs; ``--component NAME`` for one); ``--write`` rewrites the
outputs from the FMUs. The integration tests and each FMU's FMI-LS-REF smoke test
(:mod:`glider_cosim.verify.lsref_ours`) run the same cases.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..components import COMPONENTS, component
from ..master.cosimulation import CoSimulation
from ..master.spec import System
from ..runner.recorders import ArrayRecorder, csv_lines

STEP = 0.02
STOP = 10.0
#: absolute tolerance of the comparison (rad, m/s, m)
ATOL = 1e-9


def _cases() -> dict[str, dict[str, Any]]:
    return {
        c.model: {"folder": c.folder, "parameters": dict(c.reference), "component": c.name}
        for c in COMPONENTS
        if (c.folder / "reference_input.csv").is_file()
    }


#: model name -> its reference case: its folder (the CSVs) and parameters, for every
#: registered component whose folder holds a ``reference_input.csv``
CASES = _cases()


def cases_asked(name: str | None) -> list[str]:
    """The model names of the reference cases ``--component name`` asks for (None: every
    one).

    Raises
    ------
    ValueError
        ``name`` is not a registered component, or its folder has no reference case.
    """
    if name is None:
        return list(CASES)
    model = component(name).model  # UnknownComponentError names the known ones
    if model not in CASES:
        raise ValueError(f"component {name!r} has no reference_input.csv in its folder")
    return [model]


def reference_inputs(name: str) -> tuple[list[str], np.ndarray]:
    """Input table (time + one column per input) of a component's reference case, read
    from its ``reference_input.csv``."""
    return read_csv(CASES[name]["folder"] / "reference_input.csv")


def run_reference(
    name: str, fmu: Path, inputs: tuple[list[str], np.ndarray] | None = None
) -> tuple[list[str], np.ndarray]:
    """Run ``fmu`` alone on an input table (default: its reference inputs).

    Returns (columns, data) with one row per communication point.
    """
    cols, table = inputs if inputs is not None else reference_inputs(name)
    times = list(table[:, 0])
    system = System(
        fmus={"fmu": Path(fmu)},
        connections=[],
        parameters={"fmu": CASES[name]["parameters"]},
        tables={f"fmu.{c}": (times, list(table[:, i + 1])) for i, c in enumerate(cols[1:])},
    )
    sim = CoSimulation(system, step=STEP)
    rec = ArrayRecorder()
    try:
        sim.run(times[-1], rec)
    finally:
        sim.close()
    return [c.removeprefix("fmu.") for c in rec.columns], rec.array()


def write_csv(path: Path, columns: list[str], data: np.ndarray) -> None:
    """``columns`` and the rows of ``data`` as CSV, each value as ``repr`` writes it."""
    Path(path).write_bytes((",".join(columns) + "\n").encode() + csv_lines(data))


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    with open(path) as f:
        cols = f.readline().strip().split(",")
    return cols, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def compare(name: str, fmu: Path) -> tuple[bool, str]:
    """Run ``name``'s reference case on ``fmu`` and compare with ``reference_output.csv``:
    (equal within :data:`ATOL`, one line saying so)."""
    expected = CASES[name]["folder"] / "reference_output.csv"
    if not expected.is_file():
        return False, (
            f"{name}: no reference_output.csv in {expected.parent}: expected the FMU's "
            f"outputs on reference_input.csv (write them with --write)"
        )
    cols, data = run_reference(name, fmu)
    ref_cols, ref = read_csv(expected)
    if cols != ref_cols or data.shape != ref.shape:
        return False, f"{name}: columns {cols} or {data.shape[0]} rows differ from the reference"
    worst = float(np.max(np.abs(data - ref))) if data.size else 0.0
    ok = worst <= ATOL
    verdict = "equal to" if ok else "differs from"
    return ok, (
        f"{name}: {len(data)} rows, {len(cols) - 1} outputs, {verdict} reference_output.csv "
        f"(largest difference {worst:.3g}, tolerance {ATOL:g})"
    )


def main(argv: list[str] | None = None) -> int:
    """Run the reference cases (``--write``: rewrite their outputs); 0 if all equal."""
    from ..fmus.folders import prepare_fmus

    ap = argparse.ArgumentParser(
        prog="python -m glider_cosim.verify.reference",
        description="Run each component's FMU alone on its reference_input.csv and compare "
        "with its reference_output.csv (exit 1 if one differs).",
    )
    ap.add_argument("--component", default=None, help="one component (default: every one)")
    ap.add_argument("--write", action="store_true", help="rewrite the reference outputs")
    ap.add_argument("--fmu-dir", default=None, help="our FMUs (default: the per-user cache)")
    args = ap.parse_args(argv)
    try:
        names = cases_asked(args.component)
    except ValueError as err:
        ap.error(str(err))
    # the Python flavor's FMUs, from the per-user cache (built for this machine if
    # missing or stale) or the folder given
    folder = prepare_fmus(args.fmu_dir, None, host_only=True)
    fmus = {name: folder / f"{name}.fmu" for name in names}
    failed = 0
    for name in names:
        if args.write:
            cols, data = run_reference(name, fmus[name])
            write_csv(CASES[name]["folder"] / "reference_output.csv", cols, data)
            print(f"{name}: {len(data)} rows, {len(cols) - 1} outputs written")
            continue
        ok, line = compare(name, fmus[name])
        failed += not ok
        print(line)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
