"""Benchmark: the exported SSP in Ecos, libcosim and our master, in one run (us per step).

Usage: python bench/hosts.py [--steps N] [--repeat R] [--json]

``glider-cosim export-ssp`` of the default scenario (three FMUs on our runtime, 50 Hz) is
stepped N times (default 1500, 30 s) after initialisation in each host, each in a
process of its own, no results recorded by any of them; reported: the median wall time
per macro step, best of R runs (default 3), and ours / Ecos (target <= 0.8).

- Ecos: ``pip install ecospy`` (0.7.2 here). Its binary needs oneTBB: on Debian
  ``apt-get install libtbb12``; without it ``import ecospy`` fails with ``OSError:
  libtbb.so.12: cannot open shared object file``. Ecos steps the instances on its
  thread pool (threads Python has never seen).
- libcosim: libcosimpy (a dependency), ``CosimExecution.from_ssp_file``; its thread pool too.
- ours: ``glider_cosim.interop.ssp_import.load_ssp`` and
  :class:`~glider_cosim.master.CoSimulation` with Jacobi coupling (the scheme the other two use).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ECOS = """
import json, statistics, sys, time
from ecospy import EcosSimulation
sim = EcosSimulation(step_size=float(sys.argv[2]), ssp_path=sys.argv[1])
sim.init()
times = []
for _ in range(int(sys.argv[3])):
    t0 = time.perf_counter()
    sim.step()
    times.append(time.perf_counter() - t0)
sim.terminate()
sim.free()
print(json.dumps(statistics.median(times)))
"""

LIBCOSIM = """
import json, statistics, sys, time
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
log_output_level(CosimLogLevel.ERROR)
ex = CosimExecution.from_ssp_file(sys.argv[1])
ex.step()  # initialisation
times = []
for _ in range(int(sys.argv[3])):
    t0 = time.perf_counter()
    ex.step()
    times.append(time.perf_counter() - t0)
del ex  # free the instances while Python runs
print(json.dumps(statistics.median(times)))
"""

OURS = """
import json, statistics, sys, time
from glider_cosim.master import CoSimulation
from glider_cosim.interop.ssp_import import load_ssp
system, step, _ = load_ssp(sys.argv[1])
sim = CoSimulation(system, step=step, coupling="jacobi")
sim.initialize()
times = []
clock = time.perf_counter
for _ in range(int(sys.argv[3])):
    t0 = clock()
    sim.do_step()
    times.append(clock() - t0)
sim.close()
print(json.dumps(statistics.median(times)))
"""

HOSTS = {"ecos": ECOS, "libcosim": LIBCOSIM, "ours": OURS}


def us_per_step(code: str, ssp: Path, step: float, steps: int) -> float | str:
    """Median us per step, or the error's last line if the host cannot run."""
    p = subprocess.run([sys.executable, "-c", code, str(ssp), repr(step), str(steps)],
                       capture_output=True, text=True, timeout=900)  # fmt: skip
    if p.returncode != 0:
        return (p.stderr.strip().splitlines() or [f"exit {p.returncode}"])[-1]
    return float(p.stdout.strip().splitlines()[-1]) * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--fmu-dir", default="fmus")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    from glider_cosim.fmus.folders import build_all
    from glider_cosim.interop.ssp_export import export_ssp
    from glider_cosim.scenarios.scenario import load_scenario

    build_all(Path(args.fmu_dir), only_stale=True)
    step = load_scenario(None).step
    result: dict[str, object] = {}
    with tempfile.TemporaryDirectory() as tmp:
        ssp = export_ssp(Path(tmp) / "default.ssp", None, Path(args.fmu_dir))
        for name, code in HOSTS.items():
            runs = [us_per_step(code, ssp, step, args.steps) for _ in range(args.repeat)]
            times = [r for r in runs if isinstance(r, float)]
            result[f"{name}_us_per_step"] = round(min(times), 1) if times else runs[-1]
    ecos, ours = result["ecos_us_per_step"], result["ours_us_per_step"]
    if isinstance(ecos, float) and isinstance(ours, float):
        result["ours_to_ecos"] = round(ours / ecos, 3)
    if not args.json:
        for k, v in result.items():
            print(f"{k:20s} {v}")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
