"""Benchmark: the native FMI overhead split by timing, not sampling: the loop, the run's
prologue, and what fresh instances add.

Usage: python bench/overhead_timed.py [--rounds 15] [--runs 20] [--fmu-dir DIR] [--json]

The default scenario (3000 macro steps, rows in memory), native FMUs, one process. Each
round times ``--runs`` runs of each kind below, the kinds alternated (this machine's speed
moves by a third from minute to minute; alternation gives every kind the same spells):

- ``floor``: the same C models in one C loop, no FMI
  (:class:`glider_cosim.runner.monolithic.NativeMonolithic`; its reset not timed);
- ``advance``: one ``CoSimulation`` reused, reset and its first point outside the timer,
  :meth:`~glider_cosim.master.cosimulation.CoSimulation.advance` timed: the master's C
  block loop (3 ``fmi2DoStep`` and 6 batched gets and sets a step, a recorded row) and the
  Python around each block of 256 steps;
- ``reused_run``: the same instance reset, :meth:`CoSimulation.run` timed (what ``run``
  adds to ``advance``: its signal handlers, the recorder's start, the first point);
- ``fresh_run``: a new ``CoSimulation`` each run, initialised outside the timer, ``run``
  timed: what ``bench/cosim_step.py`` times as the native run (first calls into fresh
  instances, the block loop's set-up, fresh memory).

Figures are the best round's (each round's time over its runs), in us per macro step,
and the differences: ``loop_overhead`` = advance - floor, ``run_prologue_us`` and
``fresh_instances_us`` per run, ``overhead`` = fresh_run - floor (the bench's FMI
overhead). Medians of the rounds are given too.
"""

from __future__ import annotations

import argparse
import statistics
import time

from _common import emit

from glider_cosim.fmus.folders import prepare_fmus
from glider_cosim.master.cosimulation import CoSimulation
from glider_cosim.runner.monolithic import NativeMonolithic
from glider_cosim.runner.recorders import ArrayRecorder
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for

KINDS = ("floor", "advance", "reused_run", "fresh_run")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=15, help="alternated rounds (default: 15)")
    ap.add_argument("--runs", type=int, default=20, help="runs of each kind a round (default: 20)")
    ap.add_argument("--fmu-dir", default=None, help="native FMUs (default: the per-user cache)")
    ap.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = ap.parse_args()
    if args.rounds < 1 or args.runs < 1:
        raise SystemExit(f"--rounds {args.rounds} --runs {args.runs}: expected both >= 1")
    sc = load_scenario(None)
    fmu_dir = prepare_fmus(args.fmu_dir, "native").resolve()
    n = round(sc.stop_time / sc.step)

    def new_sim() -> CoSimulation:
        sim = CoSimulation(system_for(sc, fmu_dir), step=sc.step, coupling=sc.coupling)
        sim.initialize()
        return sim

    floor = NativeMonolithic(sc, None, fmu_dir)
    kept = new_sim()

    def time_floor() -> float:
        floor.reset()
        t0 = time.perf_counter()
        floor.run(n)
        return time.perf_counter() - t0

    def time_advance() -> float:
        kept.reset(None)
        rec = ArrayRecorder()
        rec.start(kept.columns)
        rec.row(kept.communication_point())
        t0 = time.perf_counter()
        kept.advance(n, rec)
        return time.perf_counter() - t0

    def time_reused_run() -> float:
        kept.reset(None)
        t0 = time.perf_counter()
        kept.run(sc.stop_time, ArrayRecorder())
        return time.perf_counter() - t0

    def time_fresh_run() -> float:
        sim = new_sim()
        try:
            t0 = time.perf_counter()
            sim.run(sc.stop_time, ArrayRecorder())
            return time.perf_counter() - t0
        finally:
            sim.close()

    timers = dict(zip(KINDS, (time_floor, time_advance, time_reused_run, time_fresh_run)))
    for timer in timers.values():  # first calls, first allocations
        timer()
    rounds: dict[str, list[float]] = {k: [] for k in KINDS}
    for _ in range(args.rounds):
        for kind, timer in timers.items():
            rounds[kind].append(sum(timer() for _ in range(args.runs)) / (args.runs * n) * 1e6)
    kept.close()
    best = {k: min(v) for k, v in rounds.items()}
    med = {k: statistics.median(v) for k, v in rounds.items()}
    result: dict = {"rounds": args.rounds, "runs_per_round": args.runs, "steps_per_run": n}
    for label, fig in (("", best), ("median_", med)):
        for k in KINDS:
            result[f"{label}{k}_us_per_macro_step"] = round(fig[k], 4)
        result[f"{label}loop_overhead_us_per_macro_step"] = round(fig["advance"] - fig["floor"], 4)
        result[f"{label}run_prologue_us"] = round((fig["reused_run"] - fig["advance"]) * n, 1)
        result[f"{label}fresh_instances_us"] = round((fig["fresh_run"] - fig["reused_run"]) * n, 1)
        result[f"{label}overhead_us_per_macro_step"] = round(fig["fresh_run"] - fig["floor"], 4)
    emit(result, args.json)


if __name__ == "__main__":
    main()
