"""Reference input/output CSVs of each FMU run alone (kept beside each component).

``python -m glider_cosim.verify.reference --write`` regenerates them; the integration tests
run each FMU on ``reference_input.csv`` and compare with ``reference_output.csv``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

import glider_controller
import glider_observer
import glider_plant

from ..master.cosimulation import CoSimulation
from ..master.spec import System
from ..runner.recorders import ArrayRecorder, csv_lines

STEP = 0.02
STOP = 10.0
#: relative/absolute tolerance of the comparison (rad, m/s, m)
ATOL = 1e-9

CASES = {
    "GliderPlant": {
        "folder": Path(glider_plant.__file__).parent,
        "parameters": {"noise_std": 0.01, "noise_seed": 7},
        "inputs": {
            "delta_cmd": lambda t: math.radians(20.0) if 2.0 <= t < 6.0 else 0.0,
            "F_x": lambda t: 0.0,
            "F_z": lambda t: 0.2 if 7.0 <= t < 8.0 else 0.0,
            "M_y": lambda t: 0.0,
        },
    },
    "GliderObserver": {
        "folder": Path(glider_observer.__file__).parent,
        "parameters": {"start_at_equilibrium": True},
        "inputs": {
            "theta_meas": lambda t: math.radians(-21.0 - 3.0 * math.exp(-t / 2) * math.cos(2 * t)),
            "delta_cmd": lambda t: math.radians(2.0) if t >= 5.0 else 0.0,
        },
    },
    "GliderController": {
        "folder": Path(glider_controller.__file__).parent,
        "parameters": {"law": 3, "K_P": 2.0, "K_I": 1.0, "t_enable": 1.0},
        "inputs": {
            "V_hat": lambda t: 0.2 + 0.003 * t,
            "theta_g_hat": lambda t: math.radians(-35.0 + 2.0 * t),
        },
    },
}


def reference_inputs(name: str) -> tuple[list[str], np.ndarray]:
    """Input table (time + one column per input) of a component's reference case."""
    case = CASES[name]
    n = round(STOP / STEP)
    t = [k * STEP for k in range(n + 1)]
    cols = list(case["inputs"])
    data = np.array([[tk] + [case["inputs"][c](tk) for c in cols] for tk in t])
    return ["time"] + cols, data


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
        sim.run(STOP, rec)
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


def main(argv: list[str] | None = None) -> None:
    from ..fmus.folders import build_all, fmu_folder

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="rewrite the reference CSVs")
    ap.add_argument("--fmu-dir", default=None, help="our FMUs (default: the per-user cache)")
    args = ap.parse_args(argv)
    fmus = build_all(fmu_folder(args.fmu_dir), only_stale=True)
    for name, case in CASES.items():
        cols, data = run_reference(name, fmus[name])
        in_cols, in_data = reference_inputs(name)
        if args.write:
            write_csv(case["folder"] / "reference_input.csv", in_cols, in_data)
            write_csv(case["folder"] / "reference_output.csv", cols, data)
        print(f"{name}: {len(data)} rows, {len(cols) - 1} outputs")


if __name__ == "__main__":
    main()
