"""Benchmark: microseconds per macro step of the default scenario (3 FMUs, recording on),
against the same sampled loop calling the model code directly (no FMI).

Usage: python bench/cosim_step.py [--json] [--repeat N] [--native-only] [--cli-only]
       [--wasm-only] [--paths-only] [--fresh-font-cache]
The last line with --json is one JSON object (figures quoted in
docs/explanation/performance.md). --native-only skips the Python flavor, libcosim and the
cold run. --cli-only measures the command line alone: ``glider-cosim run`` with and
without plots (median of 5 warm runs each, both flavors) and ``glider-cosim --help``.
--wasm-only measures the FMI 3.0 native FMUs' WebAssembly components under wasmtime
(``run --flavor wasm``) beside the same FMUs' native libraries, alone. --paths-only
measures the master's two paths alone, in memory, both flavors: the C fast loop over the
instances fmpy created, and the fmpy path (``GLIDER_COSIM_FASTLOOP=0``), interleaved.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from _common import emit

from glider_cosim.fmus.folders import build_all
from glider_cosim.master import CoSimulation
from glider_cosim.master.fastloop import ENV, FastLoop
from glider_cosim.runner import monolithic
from glider_cosim.runner.monolithic import COLUMNS, simulate_monolithic
from glider_cosim.runner.parquet import ParquetFormatError, ParquetRecorder, require_pyarrow
from glider_cosim.runner.recorders import ArrayRecorder, CsvRecorder, csv_lines
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for


def cosim_step_times(fmu_dir: Path, out: Path) -> list[float]:
    """Per-macro-step wall times (s) of the default scenario under the master."""
    sc = load_scenario(None)
    sim = CoSimulation(system_for(sc, fmu_dir), step=sc.step, coupling=sc.coupling)
    rec = CsvRecorder(out / "results.csv")
    times = []
    try:
        sim.initialize()
        rec.start(sim.columns)
        rec.row(sim.communication_point())
        n = round(sc.stop_time / sc.step)
        clock = time.perf_counter
        for _ in range(n):
            t0 = clock()
            sim.do_step()
            rec.row(sim.communication_point())
            times.append(clock() - t0)
    finally:
        rec.close()
        sim.close()
    return times


def run_seconds_per_step(fmu_dir: Path, recorder_for, repeat: int) -> float:
    """Best of ``repeat`` runs of the default scenario through :meth:`CoSimulation.run`
    (the master's own loop: the C fast loop in blocks), seconds per macro step."""
    return runs_seconds_per_step(fmu_dir, {"run": recorder_for}, repeat)["run"]


def runs_seconds_per_step(fmu_dir: Path, recorders: dict, repeat: int) -> dict[str, float]:
    """:func:`run_seconds_per_step` for several recorders (name -> factory), their runs
    interleaved (one of each per round: the same load for all), best of ``repeat`` each.
    The time includes the recorder's ``close`` (a CSV's last write)."""
    sc = load_scenario(None)
    n = round(sc.stop_time / sc.step)
    best = dict.fromkeys(recorders, float("inf"))
    for _ in range(repeat):
        for name, recorder_for in recorders.items():
            sim = CoSimulation(system_for(sc, fmu_dir), step=sc.step, coupling=sc.coupling)
            rec = recorder_for()
            try:
                sim.initialize()  # FMU loading and initialisation are not in the figure
                t0 = time.perf_counter()
                sim.run(sc.stop_time, rec)
                rec.close()
                best[name] = min(best[name], (time.perf_counter() - t0) / n)
            finally:
                rec.close()
                sim.close()
    return best


def paths_seconds_per_step(fmu_dir: Path, repeat: int) -> dict[str, float]:
    """The default scenario in memory through :meth:`CoSimulation.run`, once on the C
    fast loop (over the instances fmpy created) and once on the fmpy path
    (``GLIDER_COSIM_FASTLOOP=0``: every call through ``FMU2Slave``'s methods), one of
    each per round, best of ``repeat`` each; seconds per macro step."""
    sc = load_scenario(None)
    n = round(sc.stop_time / sc.step)
    best = {"c_loop": float("inf"), "fmpy": float("inf")}
    old = os.environ.get(ENV)
    try:
        for _ in range(repeat):
            for name, value in (("c_loop", "1"), ("fmpy", "0")):
                os.environ[ENV] = value
                sim = CoSimulation(system_for(sc, fmu_dir), step=sc.step, coupling=sc.coupling)
                try:
                    sim.initialize()
                    if (sim._fast is not None) != (value == "1"):
                        raise SystemExit(f"bench: {ENV}={value} took the other path")
                    t0 = time.perf_counter()
                    sim.run(sc.stop_time, ArrayRecorder())
                    best[name] = min(best[name], (time.perf_counter() - t0) / n)
                finally:
                    sim.close()
    finally:
        if old is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = old
    return best


def wasm_and_native_fmi3(fmi3_dir: Path, repeat: int) -> tuple[float, float]:
    """The FMI 3 native FMUs run in memory (as :func:`runs_seconds_per_step`) by their
    WebAssembly components under wasmtime (``run --flavor wasm``) and by their native
    libraries, alternated (one of each per round), best of ``repeat`` each. Seconds per
    macro step."""
    from glider_cosim.master.wasm import components

    wasm = native = float("inf")
    for _ in range(repeat):
        with components():
            wasm = min(wasm, runs_seconds_per_step(fmi3_dir, {"mem": ArrayRecorder}, 1)["mem"])
        native = min(native, runs_seconds_per_step(fmi3_dir, {"mem": ArrayRecorder}, 1)["mem"])
    return wasm, native


def native_and_floor(native_dir: Path, repeat: int) -> tuple[float, float]:
    """The native in-memory run (as :func:`runs_seconds_per_step`) and the C floor
    (:func:`glider_cosim.runner.monolithic.seconds_per_step`: the same models in one C
    loop, initialisation not included) alternated, one of each per round, best of
    ``repeat`` each: both see the same load (this machine's speed moves by 30 % from one
    minute to the next), so their difference is the FMI overhead. Seconds per step."""
    sc = load_scenario(None)
    n = round(sc.stop_time / sc.step)
    loop = monolithic.NativeMonolithic(sc, None, native_dir)
    native = floor = float("inf")
    for _ in range(repeat):
        native = min(native, runs_seconds_per_step(native_dir, {"mem": ArrayRecorder}, 1)["mem"])
        loop.reset()
        t0 = time.perf_counter()
        loop.run(n)
        floor = min(floor, (time.perf_counter() - t0) / n)
    return native, floor


def new_file(factory: Any, path: Path) -> Any:
    """A recorder factory writing ``path`` as a new file, as a run does (``run`` and
    ``simulate`` remove an earlier run's files before it starts): the file an earlier
    round left there is removed first, outside the timed run. Writing over it instead
    (``native_csv_replacing``) adds what the file system takes to free it: 0.5-0.9 ms
    for the run's 600 kB on this machine's ext4, a third of the CSV's cost."""

    def make() -> Any:
        path.unlink(missing_ok=True)
        return factory(path)

    return make


def csv_seconds_per_row(out: Path, n: int = 30000, ncol: int = 17) -> float:
    """What the CSV recorder costs per row of ``ncol`` values (Python's repr), s."""
    import random

    rng = random.Random(1)
    rows = [tuple(rng.uniform(-1, 1) for _ in range(ncol)) for _ in range(256)]
    rec = CsvRecorder(out / "csv_cost.csv")
    rec.start([f"c{i}" for i in range(ncol)])
    t0 = time.perf_counter()
    for i in range(n):
        rec.row(rows[i % 256])
    rec.close()
    return (time.perf_counter() - t0) / n


def format_seconds_per_value(native_dir: Path, repeat: int) -> float:
    """Best of ``repeat`` formattings of the native default run's rows (3001 x 17 values,
    in memory) into CSV text (``csv_lines``: Python's repr), s per value."""
    sc = load_scenario(None)
    sim = CoSimulation(system_for(sc, native_dir), step=sc.step, coupling=sc.coupling)
    rec = ArrayRecorder()
    try:
        sim.run(sc.stop_time, rec)
    finally:
        sim.close()
    rows = rec.array()
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        csv_lines(rows)
        best = min(best, time.perf_counter() - t0)
    return best / rows.size


def native_breakdown(native_dir: Path, repeat: int) -> dict[str, float]:
    """Where the native flavor's time per macro step goes, s: ``glider_run`` (the fast
    loop of ``CoSimulation.run``) over the same instances with only the three
    fmi2DoSteps (no exchange: inputs held), and with only the exchange (the planned
    fmi2GetReal/fmi2SetReal calls and the recorded row, no step). Best of ``repeat``
    blocks of 256 steps each, from a state 2 s into the default run."""
    sc = load_scenario(None)
    sim = CoSimulation(system_for(sc, native_dir), step=sc.step, coupling=sc.coupling)
    try:
        sim.initialize()
        sim.run(2.0, ArrayRecorder())  # warm, and the fast loop set up with its record
        fast = sim._fast
        nops, nsteps = fast._nops, fast._nsteps
        out, k = {}, sim.k
        for name, ops, steps in (("steps", 0, nsteps.value), ("exchange", nops.value, 0)):
            fast._nops, fast._nsteps = ctypes.c_int(ops), ctypes.c_int(steps)
            best = float("inf")
            for _ in range(repeat):
                t0 = time.perf_counter()
                done, where = fast.run(sim.t0, k, sim.step_size, FastLoop.RUN_BLOCK)[:2]
                best = min(best, (time.perf_counter() - t0) / done)
                if where >= 0:
                    raise SystemExit(f"bench: the {name}-only loop failed after {done} steps")
                k += done if steps else 0  # each doStep from the instances' own time
            out[name] = best
        fast._nops, fast._nsteps = nops, nsteps
    finally:
        sim.close()
    return out


def monolithic_step_times(fmu_dir: Path, out: Path) -> list[float]:
    """Per-step wall times (s) of the same loop without FMI, recording the same CSV."""
    times: list[float] = []
    last = [0.0]
    rec = CsvRecorder(out / "monolithic.csv")

    def row(r):
        rec.row(r)
        now = time.perf_counter()
        times.append(now - last[0])
        last[0] = now

    simulate_monolithic(load_scenario(None), fmu_dir=fmu_dir, stop_time=1.0)  # scipy import
    rec.start(COLUMNS)
    last[0] = time.perf_counter()
    simulate_monolithic(load_scenario(None), row=row, fmu_dir=fmu_dir)
    rec.close()
    return times[1:]


LIBCOSIM_TIMING = """
import json, statistics, sys, time
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimObserver import CosimObserver
log_output_level(CosimLogLevel.ERROR)
ex = CosimExecution.from_ssp_file(sys.argv[1])
ex.add_observer(CosimObserver.create_last_value())  # recording on
ex.step()  # initialisation
times = []
for _ in range(int(sys.argv[2])):
    t0 = time.perf_counter()
    ex.step()
    times.append(time.perf_counter() - t0)
del ex  # free the instances while Python runs, not in the interpreter's finalization
print(json.dumps(statistics.median(times)))
"""


def libcosim_step_seconds(fmu_dir: Path, out: Path) -> float:
    """Median seconds per macro step of libcosimpy on the exported default SSP."""
    from glider_cosim.interop.ssp_export import export_ssp

    ssp = export_ssp(out / "default.ssp", None, fmu_dir)
    p = subprocess.run([sys.executable, "-c", LIBCOSIM_TIMING, str(ssp), "2999"],
                       check=True, capture_output=True, text=True)  # fmt: skip
    return float(p.stdout.strip().splitlines()[-1])


def parquet_seconds_per_step(fmu_dir: Path, out: Path, repeat: int) -> float | None:
    """:func:`run_seconds_per_step` recording to Parquet; None (with a note on stderr)
    where pyarrow is not installed."""
    try:
        require_pyarrow()
    except ParquetFormatError:
        print(
            "note: native_parquet_us_per_macro_step skipped: pyarrow is not installed "
            "(pip install 'glider-cosim[parquet]')",
            file=sys.stderr,
        )
        return None
    return run_seconds_per_step(fmu_dir, lambda: ParquetRecorder(out / "native.parquet"), repeat)


def cold_run_seconds(fmu_dir: Path, out: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, "-c", "from glider_cosim.cli import console_main; console_main()",
         "run", "--out", str(out / "cold"), "--fmu-dir", str(fmu_dir)],
        check=True, capture_output=True,
    )  # fmt: skip
    return time.perf_counter() - t0


#: ``--fresh-font-cache``: each command with a new, empty matplotlib font cache (the CLI
#: before it kept one in its cache folder: the fonts were scanned again at every run)
FRESH_FONTS: list[Path] = []


def _cli_seconds(*args: str) -> float:
    env = None
    if FRESH_FONTS:
        env = {**os.environ, "MPLCONFIGDIR": tempfile.mkdtemp(dir=FRESH_FONTS[0])}
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "from glider_cosim.cli import console_main; "
                    "console_main()", *args], check=True, capture_output=True, env=env)  # fmt: skip
    return time.perf_counter() - t0


def cli_seconds(fmu_dir: Path | None, out: Path, native_dir: Path) -> dict[str, float]:
    """``glider-cosim run`` of the default scenario with plots and with ``--no-plots``,
    median of 5 warm runs each (one run of each first to warm the FMUs and file caches),
    the two alternated (with, without, with, ...: this machine's speed drifts by a third
    within a minute, and five runs of one after five of the other measured the drift),
    the Python flavor (with ``fmu_dir``) and the native one; ``glider-cosim --help``."""
    found = {}
    for prefix, folder in (("", fmu_dir), ("native_", native_dir)):
        if folder is None:
            continue
        options = (("cli_run_s", ()), ("cli_run_no_plots_s", ("--no-plots",)))
        runs = {key: ("run", "--out", str(out / f"cli-{prefix}{key}"), "--fmu-dir", str(folder),
                      *extra) for key, extra in options}  # fmt: skip
        times: dict[str, list[float]] = {key: [] for key in runs}
        for k in range(6):
            for key, run in runs.items():
                seconds = _cli_seconds(*run)
                if k:  # the first of each warms
                    times[key].append(seconds)
        for key, seen in times.items():
            found[prefix + key] = round(statistics.median(seen), 3)
        found[prefix + "cli_plots_ratio"] = round(
            found[prefix + "cli_run_s"] / found[prefix + "cli_run_no_plots_s"], 3
        )
    _cli_seconds("--help")
    found["cli_help_s"] = round(statistics.median(_cli_seconds("--help") for _ in range(5)), 3)
    return found


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object last")
    ap.add_argument("--repeat", type=int, default=3, help="runs; the best median is kept")
    ap.add_argument("--fmu-dir", default="fmus", help="the Python flavor's FMUs")
    ap.add_argument("--native-dir", default="fmus/native", help="the native flavor's FMUs")
    ap.add_argument("--native-only", action="store_true", help="the native figures alone")
    ap.add_argument("--cli-only", action="store_true", help="the command line's figures alone")
    ap.add_argument("--wasm-only", action="store_true", help="the WebAssembly figures alone")
    ap.add_argument("--paths-only", action="store_true",
                    help="the C loop and the fmpy path alone, in memory")  # fmt: skip
    ap.add_argument("--fmi3-dir", default="fmus/fmi3/native",
                    help="the native FMI 3 FMUs (with their WebAssembly components)")  # fmt: skip
    ap.add_argument("--fresh-font-cache", action="store_true",
                    help="each command with a new, empty matplotlib font cache (as before "
                         "the CLI kept it)")  # fmt: skip
    args = ap.parse_args()
    fmu_dir = Path(args.fmu_dir)
    native_dir = Path(args.native_dir)
    fmi3_dir = Path(args.fmi3_dir)
    if args.paths_only:
        build_all(native_dir, only_stale=True, flavor="native")
        build_all(fmu_dir, only_stale=True, flavor="python")
        paths = {}
        for flavor, folder in (("native", native_dir), ("python", fmu_dir)):
            for name, sec in paths_seconds_per_step(folder, args.repeat * 3).items():
                paths[f"{flavor}_{name}_us_per_macro_step"] = round(sec * 1e6, 2)
        paths["scenario"] = ("default (60 s, 3 FMUs, 50 Hz), CoSimulation.run in memory, "
                             "initialisation not included; best of the rounds")  # fmt: skip
        emit({**paths, "load_average": os.getloadavg(), "cpus": os.cpu_count()}, args.json)
        return
    build_all(fmi3_dir, only_stale=True, flavor="native", fmi=3)
    wasm, native3 = wasm_and_native_fmi3(fmi3_dir, args.repeat)
    result: dict = {
        "wasm_us_per_macro_step": round(wasm * 1e6, 1),
        "native_fmi3_us_per_macro_step": round(native3 * 1e6, 2),
    }
    if args.wasm_only:
        emit({**result, "load_average": os.getloadavg(), "cpus": os.cpu_count()}, args.json)
        return
    if not args.native_only:
        build_all(fmu_dir, only_stale=True, flavor="python")
    build_all(native_dir, only_stale=True, flavor="native")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        if args.fresh_font_cache:
            FRESH_FONTS.append(out)
        cli = cli_seconds(None if args.native_only else fmu_dir, out, native_dir)
        if args.cli_only:
            emit({**cli, "load_average": os.getloadavg(), "cpus": os.cpu_count()}, args.json)
            return
        runs = runs_seconds_per_step(
            native_dir,
            {
                "mem": ArrayRecorder,
                "csv": new_file(CsvRecorder, out / "native.csv"),
                "csv_replacing": lambda: CsvRecorder(out / "native_replacing.csv"),
            },
            args.repeat * 3,
        )
        native_mem, native_csv = runs["mem"], runs["csv"]
        native_paired, floor = native_and_floor(native_dir, args.repeat * 6)
        parts = native_breakdown(native_dir, args.repeat * 10)
        csv_value = format_seconds_per_value(native_dir, args.repeat)
        result.update({
            "native_us_per_macro_step": round(native_mem * 1e6, 2),
            "native_csv_us_per_macro_step": round(native_csv * 1e6, 2),
            "native_csv_over_in_memory": round(native_csv / native_mem, 2),
            "native_csv_replacing_us_per_macro_step": round(runs["csv_replacing"] * 1e6, 2),
            "csv_us_per_value": round(csv_value * 1e6, 4),
            "native_monolithic_us_per_macro_step": round(floor * 1e6, 3),
            "native_paired_us_per_macro_step": round(native_paired * 1e6, 3),
            "native_fmi_overhead_us_per_macro_step": round((native_paired - floor) * 1e6, 3),
            "native_do_steps_only_us_per_macro_step": round(parts["steps"] * 1e6, 3),
            "native_exchange_only_us_per_macro_step": round(parts["exchange"] * 1e6, 3),
        })  # fmt: skip
        if not args.native_only:
            native_parquet = parquet_seconds_per_step(native_dir, out, args.repeat * 3)
            cosim = min(
                statistics.median(cosim_step_times(fmu_dir, out)) for _ in range(args.repeat)
            )
            mono = min(
                statistics.median(monolithic_step_times(fmu_dir, out)) for _ in range(args.repeat)
            )
            cold = min(cold_run_seconds(fmu_dir, out) for _ in range(args.repeat))
            libcosim = min(libcosim_step_seconds(fmu_dir, out) for _ in range(args.repeat))
            python_mem = run_seconds_per_step(fmu_dir, ArrayRecorder, args.repeat)
            csv_row = min(csv_seconds_per_row(out) for _ in range(args.repeat))
            result.update({
                "native_parquet_us_per_macro_step": (
                    None if native_parquet is None else round(native_parquet * 1e6, 2)
                ),
                "python_in_memory_us_per_macro_step": round(python_mem * 1e6, 1),
                "csv_us_per_row": round(csv_row * 1e6, 2),
                "us_per_macro_step": round(cosim * 1e6, 1),
                "monolithic_us_per_macro_step": round(mono * 1e6, 1),
                "fmi_overhead_us_per_macro_step": round((cosim - mono) * 1e6, 1),
                "ratio_to_libcosim": round(cosim / libcosim, 3),
                "libcosim_us_per_macro_step": round(libcosim * 1e6, 1),
                "cold_run_s": round(cold, 2),
            })  # fmt: skip
        result.update(cli)
    result.update({
        "scenario": "default (60 s, 3 FMUs, 50 Hz; us_per_macro_step and monolithic: both "
        "loops recording the same CSV, step by step; native_*: CoSimulation.run in memory / "
        "to CSV; native_monolithic: the native FMUs' C models in one C loop, no FMI; "
        "native_paired: the in-memory run again, alternated with native_monolithic (one of "
        "each per round); native_fmi_overhead: native_paired minus native_monolithic; "
        "native_do_steps_only / exchange_only: the fast loop making only the 3 doSteps / "
        "only the planned gets and sets and the recorded row; csv_us_per_value: "
        "csv_lines (Python's repr) on the native run's rows; "
        "native_csv*: a new file each run (an earlier run's removed before the timer), "
        "native_csv_replacing: written over the previous run's file; "
        "wasm: the FMI 3 native FMUs' WebAssembly components under "
        "wasmtime, run --flavor wasm, in memory, alternated with native_fmi3: the same FMUs' "
        "native libraries)",
        "cpus": os.cpu_count(),
    })  # fmt: skip
    emit(result, args.json)


if __name__ == "__main__":
    main()
