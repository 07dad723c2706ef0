"""Benchmark: what loading a Python FMU's own code costs, per fmi2Instantiate.

Usage: python bench/instantiate.py [--fmu-dir fmus] [--repeat N] [--json]
Each FMU of the folder, in a fresh process per FMU (``sys.executable``), under fmpy:

- ``first_ms``: the first fmi2Instantiate of the process (Python's imports of the
  bundle, the slave's construction);
- ``again_us``: median of N more fmi2Instantiate + fmi2FreeInstance of the same
  unpacked FMU (the bundle's code hashed again, its package already imported);
- ``new_folder_us``: median of N fmi2Instantiate + fmi2FreeInstance, each of the FMU
  unpacked anew into its own folder and its binary loaded before the clock starts (as a
  host that unpacks per run): the same package, found by the code's hash.

Per-call costs (doStep, get, set) are ``bench/fmu_step.py``'s; the loading happens only
here.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import emit, parse_args

CHILD = """
import json, shutil, statistics, sys, tempfile, time
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
fmu, n = sys.argv[1], int(sys.argv[2])
md = read_model_description(fmu)
def slave(folder):
    return FMU2Slave(guid=md.guid, unzipDirectory=folder,
                     modelIdentifier=md.coSimulation.modelIdentifier, instanceName="b")
folder = extract(fmu)
s = slave(folder)
t0 = time.perf_counter(); s.instantiate(); first = time.perf_counter() - t0
def free(x):  # fmi2FreeInstance alone (fmpy's freeInstance also unloads the library)
    x.fmi2FreeInstance(x.component)
free(s)
again = []
for _ in range(n):
    t0 = time.perf_counter(); s.instantiate(); free(s)
    again.append(time.perf_counter() - t0)
new = []
for _ in range(n):
    other = extract(fmu)
    o = slave(other)
    t0 = time.perf_counter(); o.instantiate(); free(o)
    o.freeLibrary()
    new.append(time.perf_counter() - t0)
    shutil.rmtree(other, ignore_errors=True)
print(json.dumps({"first_ms": round(first * 1e3, 1),
                  "again_us": round(statistics.median(again) * 1e6, 1),
                  "new_folder_us": round(statistics.median(new) * 1e6, 1)}))
"""


def main() -> None:
    args = parse_args(__doc__, ("--repeat", {"type": int, "default": 50}))
    result = {}
    for fmu in sorted(Path(args.fmu_dir).glob("Glider*.fmu")):
        with tempfile.TemporaryDirectory() as tmp:
            p = subprocess.run([sys.executable, "-c", CHILD, str(fmu), str(args.repeat)],
                               capture_output=True, text=True, check=True,
                               env={**os.environ, "TMPDIR": tmp})  # fmt: skip
        result[fmu.stem] = json.loads(p.stdout.strip().splitlines()[-1])
    emit(result, args.json)


if __name__ == "__main__":
    main()
