"""A plain fmpy script with our three FMUs, as a user would write it (no glider_cosim).

Usage: python bench/plain_fmpy_script.py FMU_DIR [--no-free] [--steps N]
Instantiates GliderPlant, GliderObserver and GliderController with fmpy's FMU2Slave,
steps them N times (default 1000) in a closed loop at 50 Hz, then terminates and frees
them (or, with --no-free, leaves them to the process exit) and exits normally. Used by
bench/exit_stress.py and tests/integration/test_exit.py: the exit status must be 0.
"""

from __future__ import annotations

import shutil
import sys
import tempfile

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

NAMES = ("GliderPlant", "GliderObserver", "GliderController")
LINKS = [  # (source instance, output) -> (destination instance, input)
    (("GliderPlant", "theta_meas"), ("GliderObserver", "theta_meas")),
    (("GliderController", "delta_cmd"), ("GliderObserver", "delta_cmd")),
    (("GliderObserver", "V_hat"), ("GliderController", "V_hat")),
    (("GliderObserver", "theta_g_hat"), ("GliderController", "theta_g_hat")),
    (("GliderController", "delta_cmd"), ("GliderPlant", "delta_cmd")),
]


def main(argv: list[str]) -> int:
    fmu_dir = argv[0]
    free = "--no-free" not in argv
    steps = int(argv[argv.index("--steps") + 1]) if "--steps" in argv else 1000
    tmp = tempfile.mkdtemp(prefix="plain_fmpy_")
    try:
        slaves, vrs = {}, {}
        for name in NAMES:
            fmu = f"{fmu_dir}/{name}.fmu"
            md = read_model_description(fmu)
            vrs[name] = {v.name: v.valueReference for v in md.modelVariables}
            s = FMU2Slave(
                guid=md.guid,
                unzipDirectory=extract(fmu, f"{tmp}/{name}"),
                modelIdentifier=md.coSimulation.modelIdentifier,
                instanceName=name,
            )
            s.instantiate()
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            s.exitInitializationMode()
            slaves[name] = s
        h = 0.02
        for k in range(steps):
            for (src, out), (dst, inp) in LINKS:
                value = slaves[src].getReal([vrs[src][out]])
                slaves[dst].setReal([vrs[dst][inp]], value)
            for s in slaves.values():
                s.doStep(k * h, h)
        theta_g = slaves["GliderPlant"].getReal([vrs["GliderPlant"]["theta_g"]])[0]
        assert -0.7 < theta_g < -0.2, theta_g
        if free:
            for s in slaves.values():
                s.terminate()
                s.freeInstance()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
