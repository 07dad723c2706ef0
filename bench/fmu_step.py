"""Benchmark: microseconds per fmi2DoStep of each FMU, and our runtime's overhead per call.

Usage: python bench/fmu_step.py [--json] [--steps N]
Each FMU is stepped N times with inputs held (plant: tail 2 deg; observer: pitch at
equilibrium; controller: passivity law); reported per FMU:

- ``us_per_doStep``: median fmi2DoStep under fmpy (ctypes), and ``model_us_per_step``
  the model code of the same step (no FMI);
- ``runtime``: fmi2DoStep, fmi2GetReal (the outputs the loop reads) and fmi2SetReal (its
  inputs) called from C (``bench/fmi_call_timer.c``, compiled here; no Python in the
  host, so the runtime starts it), against the slave's own ``do_step``, ``get_real`` and
  ``set_real`` called directly in Python: ``overhead_us`` is the difference, what the
  runtime adds per call (target <= 0.5 us);
- ``runtime_thread``: the same from a C thread Python has never seen (a pthread of the C
  timer, as libcosim and Ecos step from): ``overhead_us`` again, target <= 0.5 us.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import fmpy
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave

from glider_controller.laws import passivity_law
from glider_cosim.fmus.folders import build_all
from glider_cosim.master.instance import _extracted
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


HERE = Path(__file__).parent
READ = {
    "GliderPlant": ("theta_meas", "V", "theta_g"),
    "GliderObserver": ("V_hat", "theta_g_hat"),
    "GliderController": ("delta_cmd",),
}


def _slave(name: str):
    """The slave class of an FMU, instantiated in this process (no FMI)."""
    from glider_controller.slave import GliderController
    from glider_observer.slave import GliderObserver
    from glider_plant.slave import GliderPlant

    cls = {"GliderPlant": GliderPlant, "GliderObserver": GliderObserver,
           "GliderController": GliderController}[name]  # fmt: skip
    return cls(instance_name="bench", resources=None)


def direct_ns(name: str, inputs: dict[str, float], n: int) -> dict[str, float]:
    """ns per call of the slave's do_step, get_real and set_real, called in Python."""
    s = _slave(name)
    vr = {v.name: vr for vr, v in s.vars.items()}
    # tuples, as the runtime passes them (the slaves key their caches on them)
    set_vrs, set_vals = tuple(vr[k] for k in inputs), list(inputs.values())
    get_vrs = tuple(vr[k] for k in READ[name])
    s.setup_experiment(0.0, None, None)
    s.set_real(set_vrs, set_vals)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    h, k = 0.02, 0
    do_step, get_real, set_real = s.do_step, s.get_real, s.set_real
    for k in range(200):
        do_step(k * h, h)
    clock = time.perf_counter
    t0 = clock()
    for k in range(201, 201 + n):
        do_step((k - 1) * h, h)
    t1 = clock()
    for _ in range(n):
        get_real(get_vrs)
    t2 = clock()
    for _ in range(n):
        set_real(set_vrs, set_vals)
    t3 = clock()
    return {"doStep_ns": (t1 - t0) / n * 1e9, "getReal_ns": (t2 - t1) / n * 1e9,
            "setReal_ns": (t3 - t2) / n * 1e9}  # fmt: skip


def runtime_ns(
    timer: Path, fmu: Path, inputs: dict[str, float], n: int, thread: bool = False
) -> dict[str, float]:
    """ns per call of the same calls through the FMU's runtime, from a C host (from a
    pthread of its own with ``thread``)."""
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    get_arg = ",".join(str(vr[k]) for k in READ[md.modelName])
    set_arg = ",".join(f"{vr[k]}={v!r}" for k, v in inputs.items())
    argv = [str(timer), _extracted(fmu), md.coSimulation.modelIdentifier, str(n), get_arg, set_arg]
    argv += ["thread"] if thread else []
    p = subprocess.run(argv, capture_output=True, text=True, timeout=600,
                       env={"PATH": "/usr/bin:/bin"})  # fmt: skip
    if p.returncode != 0:
        raise SystemExit(f"fmi_call_timer failed ({p.returncode}): {p.stderr[-500:]}")
    return json.loads(p.stdout)


def compile_timer(out: Path) -> Path:
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        raise SystemExit("bench/fmu_step.py: no C compiler for bench/fmi_call_timer.c")
    exe = out / "fmi_call_timer"
    headers = Path(fmpy.__file__).parent / "c-code"
    src = str(HERE / "fmi_call_timer.c")
    cmd = [
        cc,
        "-std=c11",
        "-O2",
        "-Wall",
        "-Wextra",
        f"-I{headers}",
        src,
        "-o",
        str(exe),
        "-ldl",
        "-lpthread",
    ]
    subprocess.run(cmd, check=True)
    return exe


def overhead(
    timer: Path, fmu: Path, name: str, n: int, repeat: int = 3, thread: bool = False
) -> dict[str, object]:
    """Best of ``repeat`` runs each way, and what the runtime adds per call (us)."""
    best_c: dict[str, float] = {}
    best_py: dict[str, float] = {}
    for _ in range(repeat):
        for best, run in ((best_c, runtime_ns(timer, fmu, INPUTS[name], n, thread)),
                          (best_py, direct_ns(name, INPUTS[name], n))):  # fmt: skip
            for k, v in run.items():
                best[k] = min(best.get(k, math.inf), v)
    return {
        "runtime_ns": {k: round(v, 1) for k, v in best_c.items()},
        "direct_ns": {k: round(v, 1) for k, v in best_py.items()},
        "overhead_us": {
            k.removesuffix("_ns"): round((best_c[k] - best_py[k]) / 1e3, 3) for k in best_c
        },  # fmt: skip
    }


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
    with tempfile.TemporaryDirectory() as tmp:
        timer = compile_timer(Path(tmp))
        result = {
            name: {
                "us_per_doStep": round(fmu_us(fmus[name], INPUTS[name], args.steps), 1),
                "model_us_per_step": round(model_us(name, args.steps), 1),
                "runtime": overhead(timer, fmus[name], name, max(args.steps, 20000)),
                "runtime_thread": overhead(
                    timer, fmus[name], name, max(args.steps, 20000), thread=True
                ),
            }
            for name in INPUTS
        }
    result["max_overhead_us"] = max(
        v for r in result.values() for v in r["runtime"]["overhead_us"].values()
    )
    result["max_thread_overhead_us"] = max(
        v
        for k, r in result.items()
        if k != "max_overhead_us"
        for v in r["runtime_thread"]["overhead_us"].values()
    )
    if not args.json:
        for name, r in result.items():
            if name.startswith("max_"):
                continue
            fmi, model = r["us_per_doStep"], r["model_us_per_step"]
            extra = ", ".join(f"{k} +{v:.3f}" for k, v in r["runtime"]["overhead_us"].items())
            thr = ", ".join(f"{k} +{v:.3f}" for k, v in r["runtime_thread"]["overhead_us"].items())
            print(f"{name:17s} doStep {fmi:6.1f} us   model {model:6.1f} us   runtime: {extra} us")
            print(f"{'':17s} from a C thread Python has never seen: {thr} us")
        print(
            f"largest runtime overhead per call: {result['max_overhead_us']:.3f} us (main "
            f"thread), {result['max_thread_overhead_us']:.3f} us (C thread)"
        )
    print(json.dumps(result))


if __name__ == "__main__":
    main()
