"""Stress the process exit: a plain fmpy script with our FMUs, run N times; count exits.

Usage: python bench/exit_stress.py [--runs N] [--cli N] [--jobs J] [--fmu-dir DIR] [--json]

Runs ``bench/plain_fmpy_script.py`` (three FMUs, 1000 steps, normal interpreter exit) N
times, alternately with and without terminate/free, J processes at a time; optionally
also ``glider-cosim run`` and a short API script ``--cli`` times each. Every exit code
must be 0: a process that aborts at exit (SIGABRT: -6) or crashes (SIGSEGV: -11) shows
up in the counts. Exit status 0 if all runs exited 0.
"""

from __future__ import annotations

import argparse
import collections
import json
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

HERE = Path(__file__).parent
API_SCRIPT = """
from glider_cosim.runner import simulate
r = simulate(None, None, fmu_dir={fmu_dir!r}, build=False, stop_time=10.0)
assert r.status == "ok", r.message
"""


FAILURES: list[dict[str, object]] = []  # the first few runs that did not exit 0


def _codes(commands: list[list[str]], jobs: int) -> dict[str, int]:
    def one(cmd: list[str]) -> int:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        if p.returncode != 0 and len(FAILURES) < 5:
            FAILURES.append({"command": cmd[1:], "exit": p.returncode,
                             "stderr": p.stderr[-1500:]})  # fmt: skip
        return p.returncode

    with ThreadPoolExecutor(jobs) as pool:
        counts = collections.Counter(pool.map(one, commands))
    return {str(k): v for k, v in sorted(counts.items())}


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--runs", type=int, default=500, help="plain fmpy script runs")
    ap.add_argument("--cli", type=int, default=0, help="glider-cosim run and API script runs")
    ap.add_argument("--jobs", type=int, default=2, help="processes at a time")
    ap.add_argument("--fmu-dir", default="fmus")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    args = ap.parse_args()
    from glider_cosim.fmus.folders import build_all

    build_all(args.fmu_dir, only_stale=True)
    t0 = time.perf_counter()
    script = str(HERE / "plain_fmpy_script.py")
    plain = [[sys.executable, script, args.fmu_dir, *(["--no-free"] if i % 2 else [])]
             for i in range(args.runs)]  # fmt: skip
    result: dict[str, object] = {
        "runs": args.runs,
        "plain_fmpy_exit_codes": _codes(plain, args.jobs),
    }
    if args.cli:
        with tempfile.TemporaryDirectory() as tmp:
            cli = [["glider-cosim", "run", "--out", f"{tmp}/{i}", "--fmu-dir", args.fmu_dir,
                    "--no-plots"] for i in range(args.cli)]  # fmt: skip
            result["cli_exit_codes"] = _codes(cli, args.jobs)
        api = [[sys.executable, "-c", API_SCRIPT.format(fmu_dir=args.fmu_dir)]] * args.cli
        result["api_exit_codes"] = _codes(api, args.jobs)
    result["seconds"] = round(time.perf_counter() - t0, 1)
    result["failures"] = FAILURES
    counts = [v for k, v in result.items() if k.endswith("_exit_codes")]
    if not args.json:
        for k, v in result.items():
            if k.endswith("_exit_codes"):
                print(f"{k}: {v}")
    print(json.dumps(result))
    sys.exit(0 if all(set(c) == {"0"} for c in counts) else 1)  # type: ignore[arg-type]


if __name__ == "__main__":
    main()
