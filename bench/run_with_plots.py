"""A whole ``glider-cosim run default`` with its plots and with ``--no-plots``, for one
or more installs, interleaved (the four or more commands in turn, ``--repeat`` rounds
after one that warms the caches): the median wall time of each, s, and each install's
ratio of the two.

``--python PY`` (repeatable; default: this interpreter): the ``glider-cosim`` script
beside each interpreter is run, e.g. main's install and a branch's venv.

Usage: python bench/run_with_plots.py [--repeat 3] [--flavor python|native]
       [--python PY ...] [--json]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import emit


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed rounds (after a warm one)")
    ap.add_argument("--flavor", choices=("python", "native"), default="python")
    ap.add_argument("--python", action="append", default=[], help="an interpreter (repeatable)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    pythons = args.python or [sys.executable]
    times: dict[tuple[int, str], list[float]] = {}
    with tempfile.TemporaryDirectory(prefix="glider-bench-plots-") as tmp:
        for k in range(args.repeat + 1):
            for i, py in enumerate(pythons):
                script = Path(py).parent / "glider-cosim"
                cmd = [str(script)] if script.exists() else [py, "-m", "glider_cosim.cli"]
                for plots in ("plots", "no_plots"):
                    out = Path(tmp) / f"{i}_{plots}"
                    extra = ["--no-plots"] if plots == "no_plots" else []
                    t0 = time.perf_counter()
                    run = [*cmd, "run", "default", "--flavor", args.flavor, "--out", str(out)]
                    subprocess.run([*run, "-q", *extra], check=True, capture_output=True)
                    if k:  # the first round warms the caches
                        times.setdefault((i, plots), []).append(time.perf_counter() - t0)
    result: dict[str, object] = {"flavor": args.flavor, "repeat": args.repeat}
    for i, py in enumerate(pythons):
        with_plots = statistics.median(times[i, "plots"])
        without = statistics.median(times[i, "no_plots"])
        result[f"python_{i}"] = py
        result[f"run_plots_s_{i}"] = round(with_plots, 3)
        result[f"run_no_plots_s_{i}"] = round(without, 3)
        result[f"plots_over_no_plots_{i}"] = round(with_plots / without, 2)
    result["load_avg_1min"] = round(os.getloadavg()[0], 2)
    emit(result, args.json)


if __name__ == "__main__":
    main()
