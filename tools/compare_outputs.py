"""Run every shipped scenario and compare results.csv and metrics.json with a reference.

Issue 53 changed the master's FMI layer (fmpy's ``FMU2Slave``/``FMU3Slave`` in place of
our own binding) and promised the same bits. This script checks that promise against
another install (e.g. main's): make the reference once with that install, then compare::

    python tools/compare_outputs.py make /tmp/ref --glider-cosim /path/to/old/glider-cosim
    python tools/compare_outputs.py compare /tmp/ref /tmp/new

``make`` runs ``glider-cosim run NAME --no-plots`` for every shipped scenario in both
flavors (python, native) and both FMI versions into ``DIR/<flavor>-<fmi>/<scenario>``;
``compare`` makes the same runs with this install (once with the C fast loop, once with
``GLIDER_COSIM_FASTLOOP=0``: the fmpy path) and compares ``results.csv`` byte for byte
and ``metrics.json`` field for field (the FMU files' paths, SHA-256 and guids, which name
the FMU cache and its builds, excepted). ``diff REF NEW`` compares two such
folders without running anything. It exits 1 and names every difference, or 0.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

FLAVORS = ("native", "python")
FMI_VERSIONS = ("2", "3")


def scenarios(cmd: str) -> list[str]:
    """The shipped scenarios' names (``glider-cosim scenarios``)."""
    out = subprocess.run([cmd, "scenarios"], capture_output=True, text=True, check=True).stdout
    return [line.split()[0] for line in out.splitlines() if line.strip()]


def run_all(cmd: str, root: Path, env: dict[str, str]) -> None:
    """Every shipped scenario, both flavors and FMI versions, into ``root``."""
    for flavor in FLAVORS:
        for fmi in FMI_VERSIONS:
            for name in scenarios(cmd):
                out = root / f"{flavor}-{fmi}" / name
                p = subprocess.run(
                    [cmd, "run", name, "--flavor", flavor, "--fmi", fmi, "--no-plots", "-q",
                     "--out", str(out)],
                    capture_output=True, text=True, env=env,
                )  # fmt: skip
                if not (out / "results.csv").is_file():
                    sys.exit(f"{flavor}-{fmi}/{name}: no results.csv ({p.stderr.strip()})")


def _metrics(path: Path) -> dict:
    data = json.loads(path.read_text())
    for fmu in data.get("run", {}).get("fmus", {}).values():
        if isinstance(fmu, dict) and "file" in fmu:
            fmu["file"] = Path(fmu["file"]).name  # the FMU cache differs
            # an FMU built elsewhere: other zip times; pythonfmu's guid is time-based
            fmu.pop("sha256", None)
            fmu.pop("guid", None)
    return data


def compare(ref: Path, new: Path) -> list[str]:
    """The differences between the runs under ``ref`` and ``new`` (empty: none)."""
    found = []
    for csv in sorted(ref.glob("*/*/results.csv")):
        rel = csv.parent.relative_to(ref)
        other = new / rel
        if not (other / "results.csv").is_file():
            found.append(f"{rel}: missing in {new}")
            continue
        if (other / "results.csv").read_bytes() != csv.read_bytes():
            found.append(f"{rel}/results.csv differs")
        if _metrics(other / "metrics.json") != _metrics(csv.parent / "metrics.json"):
            found.append(f"{rel}/metrics.json differs")
    return found


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("make", "compare", "diff"))
    ap.add_argument("reference", type=Path, help="the reference runs' folder")
    ap.add_argument("new", type=Path, nargs="?", help="compare: where this install's runs go")
    ap.add_argument("--glider-cosim", default=shutil.which("glider-cosim") or "glider-cosim",
                    help="the command that makes the runs (default: on PATH)")  # fmt: skip
    args = ap.parse_args()
    if args.what == "make":
        run_all(args.glider_cosim, args.reference, dict(os.environ))
        return 0
    if args.new is None:
        ap.error("compare needs the folder for this install's runs")
    bad = []
    for fast in ("1", "0"):
        root = args.new / f"fastloop-{fast}"
        if args.what == "compare":
            run_all(args.glider_cosim, root, {**os.environ, "GLIDER_COSIM_FASTLOOP": fast})
        bad += [f"GLIDER_COSIM_FASTLOOP={fast}: {d}" for d in compare(args.reference, root)]
    for line in bad:
        print(line)
    n = len(list(args.reference.glob("*/*/results.csv")))
    print(f"{n} runs x 2 paths compared: {len(bad)} differences")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
