"""Benchmark: where the native flavor's time per macro step goes, function by function,
against the same C models called directly in one C loop (the floor), sampled by ``perf``.

Usage: python bench/overhead_profile.py [--reps 200] [--rounds 3] [--period-us 50] [--json]

Child processes run the default scenario ``--reps`` times (3000 macro steps each,
recorded in memory), ``--rounds`` of each kind alternated: the floor
(``glider_cosim.runner.monolithic``, no FMI), and the native FMUs through the master's
C block loop (``CoSimulation.advance``), each under ``perf record -e cpu-clock`` with a
fixed sampling period. Each child times its loop
(``perf_counter``); the samples in the loop's code are then split by source file (the
FMUs' binaries carry their debug information, read with ``nm -l``):

- ``models``: the models' C files (``src/<part>/<part>_model.c``), in both loops;
- ``libm``: the math library (sin, cos, exp, atan), in both;
- ``glue``: the FMUs' model adapters (``<part>_fmu.c``: variables in, model, variables out);
- ``backend``: the native back end (``src/fmi/backend_native.c``: checks, value copies);
- ``layer``: the FMI layer (``fmi_layer.c``, ``fmi2_layer.c``: call framing, states);
- ``master``: the master's block loop (``fastloop.so``: the exchange, the rows) or the
  floor's loop (``glider_mono_run``).

Each part in us per macro step = its samples x the period / the steps run. The samples'
sum is below the timed loop by what the sampling does not attribute (the Python that
calls each block of 256 steps, the kernel). Needs ``perf`` (Debian: linux-perf); the
figures are CPU time, so they depend on the machine less than wall time, not at all on
the clock's noise.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from _common import emit

STEPS = 3000
PARTS = ("models", "libm", "glue", "backend", "layer", "master")
_FILE_PART = (
    (re.compile(r"_model\.c$"), "models"),
    (re.compile(r"_fmu\.c$"), "glue"),
    (re.compile(r"backend_native\.c$"), "backend"),
    (re.compile(r"fmi2?_layer\.c$"), "layer"),
)


def child(kind: str, reps: int) -> None:
    """Run the loop ``reps`` times; print its us per step; leave without clean-up (the
    extracted binaries stay for ``perf report``)."""
    from glider_cosim.scenarios.scenario import load_scenario

    sc = load_scenario(None)
    fmu_dir = os.environ["BENCH_FMU_DIR"]
    if kind == "floor":
        from glider_cosim.runner.monolithic import NativeMonolithic

        loop = NativeMonolithic(sc, None, fmu_dir)
        loop.reset()
        loop.run(STEPS)  # warm
        t0 = time.perf_counter()
        for _ in range(reps):
            loop.reset()
            loop.run(STEPS)
    else:
        from glider_cosim.master.cosimulation import CoSimulation
        from glider_cosim.runner.recorders import ArrayRecorder
        from glider_cosim.scenarios.system import system_for

        sim = CoSimulation(system_for(sc, Path(fmu_dir)), step=sc.step, coupling=sc.coupling)
        sim.load()
        sim.initialize()
        t0 = 0.0
        for k in range(reps + 1):
            if k == 1:
                t0 = time.perf_counter()
            if k:
                sim.reset(None)
            rec = ArrayRecorder()
            rec.start(sim.columns)
            rec.row(sim.communication_point())
            sim.advance(STEPS, rec)
    print(f"us_per_step {(time.perf_counter() - t0) / (reps * STEPS) * 1e6:.4f}", flush=True)
    os._exit(0)  # keep the extracted FMUs for perf report (the parent removes the folder)


def _symbol_files(binary: str) -> dict[str, str]:
    """Function name -> the source file it was compiled from (debug information)."""
    out = subprocess.run(["nm", "-l", "--defined-only", binary], capture_output=True,
                         text=True, check=False).stdout  # fmt: skip
    found = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 4 and parts[1] in "tT":
            found[parts[2]] = parts[3].rsplit(":", 1)[0]
    return found


def _part(dso: str, sym: str, files: dict[str, dict[str, str]], model_syms: set[str]) -> str:
    if dso.startswith("libm"):
        return "libm"
    if dso.startswith("fastloop") or sym == "glider_mono_run":
        return "master"
    if dso.startswith("monolithic"):
        return "models" if sym in model_syms else "master"
    source = files.get(dso, {}).get(sym, "")
    for pattern, part in _FILE_PART:
        if pattern.search(source):
            return part
    return "models" if sym in model_syms else ""


def profile(kind: str, reps: int, period_us: int, work: Path, fmu_dir: Path) -> dict:
    """Run one child under perf; its timed us per step and its samples by (dso, symbol)."""
    data = work / f"{kind}.perf"
    env = {**os.environ, "GLIDER_COSIM_TMP": str(work / "tmp"), "BENCH_FMU_DIR": str(fmu_dir)}
    (work / "tmp").mkdir(parents=True, exist_ok=True)
    p = subprocess.run(
        ["perf", "record", "-q", "-e", "cpu-clock", "-c", str(period_us * 1000), "-o", str(data),
         sys.executable, __file__, "--child", kind, "--reps", str(reps)],
        capture_output=True, text=True, env=env, check=False,
    )  # fmt: skip
    m = re.search(r"us_per_step ([0-9.]+)", p.stdout)
    if p.returncode != 0 or m is None:
        raise SystemExit(f"perf record of the {kind} loop failed: {p.stderr.strip()[-400:]}")
    report = subprocess.run(
        ["perf", "report", "-i", str(data), "--stdio", "--no-children", "-n", "--sort",
         "dso,sym", "-F", "sample,dso,sym"], capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    samples: dict[tuple[str, str], int] = {}
    for line in report.splitlines():
        fields = line.split()
        if len(fields) >= 4 and fields[0].isdigit() and fields[2] == "[.]":
            samples[(fields[1], fields[3])] = samples.get((fields[1], fields[3]), 0) + int(
                fields[0]
            )
    binaries = {b.name: str(b) for b in (work / "tmp").rglob("*.so")}
    return {"us_per_step": float(m.group(1)), "samples": samples, "binaries": binaries}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=200, help="runs of 3000 steps of each loop")
    ap.add_argument("--period-us", type=int, default=50, help="perf's sampling period, us")
    ap.add_argument("--rounds", type=int, default=3, help="alternated runs of each loop")
    ap.add_argument("--fmu-dir", default=None, help="native FMUs (default: the per-user cache)")
    ap.add_argument("--child", choices=("floor", "fmi"), help=argparse.SUPPRESS)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if args.child:
        child(args.child, args.reps)
    if shutil.which("perf") is None:
        raise SystemExit("perf is not installed: expected `perf` on PATH (Debian: linux-perf)")
    from glider_cosim.fmus.folders import prepare_fmus

    fmu_dir = prepare_fmus(args.fmu_dir, "native").resolve()
    work = Path(tempfile.mkdtemp(prefix="overhead_profile_"))
    try:
        runs: dict[str, dict] = {}
        for r in range(args.rounds):  # alternated: a slow spell of the machine hits both
            for kind in ("floor", "fmi"):
                got = profile(kind, args.reps, args.period_us, work / f"{kind}{r}", fmu_dir)
                run = runs.setdefault(kind, {"times": [], "samples": {}, "binaries": {}})
                run["times"].append(got["us_per_step"])
                for key, n in got["samples"].items():
                    run["samples"][key] = run["samples"].get(key, 0) + n
                run["binaries"].update(got["binaries"])
        for run in runs.values():
            run["us_per_step"] = sum(run["times"]) / len(run["times"])
        files: dict[str, dict[str, str]] = {}
        for run in runs.values():
            for name, path in run["binaries"].items():
                files.setdefault(name, _symbol_files(path))
        model_syms = {s for f in files.values() for s, src in f.items() if src.endswith("_model.c")}
        steps = args.reps * STEPS * args.rounds
        result: dict = {"reps": args.reps, "steps_per_rep": STEPS, "period_us": args.period_us}
        for kind, run in runs.items():
            parts: dict[str, float] = defaultdict(float)
            top: dict[str, float] = defaultdict(float)
            for (dso, sym), n in run["samples"].items():
                part = _part(dso, sym, files, model_syms)
                if part:
                    us = n * args.period_us / steps
                    parts[part] += us
                    top[f"{dso}:{sym}"] += us
            result[f"{kind}_us_per_macro_step"] = round(run["us_per_step"], 4)
            result[f"{kind}_us_per_macro_step_per_round"] = [round(t, 4) for t in run["times"]]
            result[f"{kind}_sampled_us"] = {p: round(parts.get(p, 0.0), 4) for p in PARTS}
            result[f"{kind}_sampled_total_us"] = round(sum(parts.values()), 4)
            result[f"{kind}_top"] = {
                k: round(v, 4) for k, v in sorted(top.items(), key=lambda kv: -kv[1])[:12]
            }
        result["overhead_us_per_macro_step"] = round(
            runs["fmi"]["us_per_step"] - runs["floor"]["us_per_step"], 4
        )
        result["difference_sampled_us"] = {
            p: round(result["fmi_sampled_us"][p] - result["floor_sampled_us"][p], 4) for p in PARTS
        }
        result["load_average"] = os.getloadavg()
        emit(result, args.json)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
