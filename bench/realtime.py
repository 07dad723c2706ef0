"""Benchmark: paced runs at 50 Hz (lateness), an external controller on loopback (round
trip per step, the highest real-time factor lockstep sustains).

Usage: python bench/realtime.py [--json] [--stop-time S] [--endpoint serve|onboard]
                                [--floor-only]
Default scenario, native FMUs, real time (rtf 1): ``--stop-time`` s of wall clock per
paced run (default 60, the scenario's), two paced runs (in process, then with the
controller outside), then libcosim's real-time mode on the SSP of the same system (when
libcosimpy is installed: the real-time factor it achieves). The last line
with --json is one JSON object.

The machine's floor, measured right after the in-process run: the same pacing in C with
no Python and no FMU (``bench/pacing_floor.c``: absolute ``clock_nanosleep`` to 1.5 ms
before each deadline, then a spin), as many points; and the share of CPU time the
hypervisor took from this virtual machine (``steal`` of /proc/stat) during each of the
two, percent. Then both again spinning through the whole period, never sleeping
(``RealTime(spin_ms=20)``, ``--spin-ms 20``: ``in_process_spin_lateness_ms``,
``c_pacer_spin_lateness_ms``). ``--floor-only``: these four runs alone.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import emit, parse_args

from glider_cosim.fmus.folders import prepare_fmus
from glider_cosim.realtime.external import Endpoint
from glider_cosim.realtime.onboard import build_onboard
from glider_cosim.realtime.pacing import RealTime
from glider_cosim.runner import simulate

CLI = "import sys; from glider_cosim.cli.main import console_main; console_main()"


def endpoint(kind: str, fmus: Path, tmp: Path) -> subprocess.Popen:
    """The controller served on 127.0.0.1 (port 0): ``glider-cosim serve`` or the
    onboard program."""
    if kind == "onboard":
        cmd = [str(build_onboard(tmp))]
    else:
        cmd = [sys.executable, "-c", CLI, "serve", "controller", "--fmu",
               str(fmus / "GliderController.fmu")]  # fmt: skip
    return subprocess.Popen([*cmd, "--listen", "udp://127.0.0.1:0"], stdout=subprocess.PIPE,
                            text=True)  # fmt: skip


def lateness(result) -> dict:
    rt = result.metrics["real_time"]
    return {**{k: round(v, 4) for k, v in rt["lateness_ms"].items()},
            "overruns": rt["overruns"], "rtf_achieved": round(rt["rtf_achieved"], 5)}  # fmt: skip


def libcosim_real_time(fmus: Path, tmp: Path, seconds: float) -> dict | None:
    """libcosim's real-time mode (libcosimpy, rtf 1, ``simulate_until``) on the SSP of the
    same system: the factor it achieves over ``seconds``, measured and as libcosim reports
    it (its per-step lateness is not visible from libcosimpy); None without libcosimpy."""
    try:
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    except ImportError:
        return None
    ssp = tmp / "default.ssp"
    subprocess.run([sys.executable, "-c", CLI, "export-ssp", str(ssp), "--fmu-dir", str(fmus)],
                   check=True, capture_output=True, timeout=600)  # fmt: skip
    log_output_level(CosimLogLevel.ERROR)
    ex = CosimExecution.from_ssp_file(str(ssp))
    ex.real_time_simulation_enabled(True)
    ex.real_time_factor_target(1.0)
    t0 = time.monotonic()
    ok = ex.simulate_until(round(seconds * 1e9))  # paced; ex.step(n) is not (libcosim's timer)
    wall = time.monotonic() - t0
    status = ex.status()
    return {"ok": bool(ok), "rtf_achieved": round(seconds / wall, 5), "wall_s": round(wall, 3),
            "rtf_reported": round(status.real_time_factor, 5)}  # fmt: skip


def cpu_jiffies() -> tuple[int, int]:
    """(steal, total) jiffies of every CPU so far (/proc/stat's first line)."""
    with open("/proc/stat") as f:
        fields = [int(v) for v in f.readline().split()[1:]]
    return fields[7], sum(fields[:8])


def steal_percent(before: tuple[int, int]) -> float:
    """The hypervisor's share of the CPU time since ``before`` (:func:`cpu_jiffies`), %."""
    steal, total = cpu_jiffies()
    return round(100.0 * (steal - before[0]) / max(1, total - before[1]), 2)


def c_pacer(points: int, tmp: Path, spin_us: int = 1500) -> dict:
    """``bench/pacing_floor.c`` compiled here (zig's cc, else the system's) and run for
    ``points`` points at 50 Hz, spinning ``spin_us`` before each: its lateness, ms, and
    the steal during it, %."""
    try:
        import ziglang  # noqa: F401

        cc = [sys.executable, "-m", "ziglang", "cc"]
    except ImportError:
        cc = [shutil.which("cc") or "gcc"]
    exe = tmp / "pacing_floor"
    if not exe.exists():  # compiled once per bench run
        src = Path(__file__).with_name("pacing_floor.c")
        subprocess.run([*cc, "-std=c99", "-O2", str(src), "-o", str(exe)], check=True)
    before = cpu_jiffies()
    p = subprocess.run([str(exe), str(points), str(spin_us)], capture_output=True, text=True,
                       check=True)  # fmt: skip
    return {**json.loads(p.stdout), "steal_pct": steal_percent(before)}


def main() -> None:
    args = parse_args(
        __doc__,
        ("--stop-time", {"type": float, "default": 60.0}),
        ("--endpoint", {"choices": ("serve", "onboard"), "default": "onboard"}),
        ("--floor-only", {"action": "store_true"}),
    )
    fmus = prepare_fmus(None, "native")
    run = {"fmu_dir": fmus, "build": False, "plots": False}
    out: dict = {"stop_time_s": args.stop_time, "step_s": 0.02, "endpoint": args.endpoint}
    before = cpu_jiffies()
    paced = simulate("default", None, stop_time=args.stop_time, real_time=RealTime(1.0), **run)
    out["in_process_lateness_ms"] = lateness(paced)
    out["in_process_steal_pct"] = steal_percent(before)
    with tempfile.TemporaryDirectory(prefix="glider-bench-rt-") as tmp:
        points = round(args.stop_time / 0.02)
        out["c_pacer_lateness_ms"] = c_pacer(points, Path(tmp))
        before = cpu_jiffies()
        spin = simulate("default", None, stop_time=args.stop_time,
                        real_time=RealTime(1.0, spin_ms=20.0), **run)  # fmt: skip
        out["in_process_spin_lateness_ms"] = lateness(spin)
        out["in_process_spin_steal_pct"] = steal_percent(before)
        out["c_pacer_spin_lateness_ms"] = c_pacer(points, Path(tmp), spin_us=20000)
        if args.floor_only:
            emit(out, args.json)
            return
        srv = endpoint(args.endpoint, fmus, Path(tmp))
        try:
            url = srv.stdout.readline().split()[-1]
            ext = {"controller": Endpoint(url)}
            t = time.perf_counter()
            lock = simulate("default", None, external=ext, **run)
            wall = time.perf_counter() - t
            c = lock.metrics["external"]["controller"]
            out["lockstep_round_trip_ms"] = {k: round(v, 4) for k, v in c["rtt_ms"].items()}
            out["lockstep_max_rtf"] = round(lock.metrics["end_time_s"] / wall, 1)
            paced = simulate("default", None, stop_time=args.stop_time,
                             real_time=RealTime(1.0), external=ext, **run)  # fmt: skip
            out["external_lateness_ms"] = lateness(paced)
            out["external_late_replies"] = paced.metrics["external"]["controller"]["late_replies"]
        finally:
            srv.kill()
            srv.wait(10)
        out["libcosim_real_time"] = libcosim_real_time(fmus, Path(tmp), args.stop_time)
    emit(out, args.json)


if __name__ == "__main__":
    main()
