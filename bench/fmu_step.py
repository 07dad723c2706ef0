"""Benchmark: microseconds per fmi2DoStep of each FMU alone under fmpy (50 Hz).

Usage: python bench/fmu_step.py [--json] [--steps N]
Each FMU is stepped N times with inputs held (plant: tail 2 deg; observer: pitch at
equilibrium; controller: passivity law); the median per call is reported, with the
model-code time of the same step (no FMI) for comparison.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from pathlib import Path

from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave

from glider_controller.laws import passivity_law
from glider_cosim.build import build_all
from glider_cosim.master import _extracted
from glider_observer.model import DEFAULT_Q, DEFAULT_R, observer_gain, observer_step
from glider_plant.model import equilibrium, plant_step
from glider_plant.params import GliderParams

P = GliderParams()
E = equilibrium(P)
INPUTS = {
    "GliderPlant": {"delta_cmd": math.radians(2.0), "F_x": 0.0, "F_z": 0.0, "M_y": 0.0},
    "GliderObserver": {"theta_meas": E.theta_g + E.alpha, "delta_cmd": 0.0},
    "GliderController": {"V_hat": 0.22, "theta_g_hat": -0.45},
}


def fmu_us(fmu: Path, inputs: dict[str, float], steps: int) -> float:
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU2Slave(
        guid=md.guid,
        unzipDirectory=_extracted(fmu),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="bench",
    )
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.setReal([vr[k] for k in inputs], list(inputs.values()))
    s.exitInitializationMode()
    do_step, comp, h = s.dll.fmi2DoStep, s.component, 0.02
    times = []
    clock = time.perf_counter
    for k in range(steps):
        t0 = clock()
        do_step(comp, k * h, h, 1)
        times.append(clock() - t0)
    s.terminate()
    s.fmi2FreeInstance(s.component)
    return statistics.median(times) * 1e6


def model_us(name: str, steps: int) -> float:
    clock = time.perf_counter
    H = observer_gain(P, DEFAULT_R, DEFAULT_Q)
    x, d, xh = (0.2, -0.5, 0.02, 0.0, 0.0, 0.0), 0.0, (E.V, E.theta_g, E.alpha, 0.0)
    times = []
    for _ in range(steps):
        t0 = clock()
        if name == "GliderPlant":
            x, d = plant_step(x, d, math.radians(2.0), 0.02, P, 0.01)
        elif name == "GliderObserver":
            xh = observer_step(xh, E.theta_g + E.alpha, 0.0, 0.02, P, H)
        else:
            passivity_law(0.22, -0.45, 10.0, P, E, math.pi / 2)
        times.append(clock() - t0)
    return statistics.median(times) * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--fmu-dir", default="fmus")
    args = ap.parse_args()
    fmus = build_all(Path(args.fmu_dir), only_stale=True)
    result = {
        name: {
            "us_per_doStep": round(fmu_us(fmus[name], INPUTS[name], args.steps), 1),
            "model_us_per_step": round(model_us(name, args.steps), 1),
        }
        for name in INPUTS
    }
    if not args.json:
        for name, r in result.items():
            fmi, model = r["us_per_doStep"], r["model_us_per_step"]
            print(f"{name:17s} doStep {fmi:6.1f} us   model {model:6.1f} us")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
