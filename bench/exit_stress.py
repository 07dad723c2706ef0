"""Stress: run `glider-cosim run` and a short API script N times each; count exit codes.

Usage: python bench/exit_stress.py [--runs N] [--json]
pythonfmu's binary can abort a process at interpreter exit ("corrupted double-linked
list", SIGABRT); this checks that neither the CLI nor a script using the API does.
"""

from __future__ import annotations

import argparse
import collections
import json
import subprocess
import sys
import tempfile
import time

API_SCRIPT = """
from glider_cosim.runner import simulate
r = simulate(None, None, fmu_dir={fmu_dir!r}, build=False, stop_time=10.0)
assert r.status == "ok", r.message
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--fmu-dir", default="fmus")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    subprocess.run([sys.executable, "-m", "glider_cosim.docs", "--check", "--fmu-dir",
                    args.fmu_dir], capture_output=True)  # builds stale FMUs  # fmt: skip
    result = {}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        cli = collections.Counter()
        for i in range(args.runs):
            p = subprocess.run(["glider-cosim", "run", "--out", f"{tmp}/{i % 3}", "--fmu-dir",
                                args.fmu_dir, "--no-plots"], capture_output=True)  # fmt: skip
            cli[p.returncode] += 1
        api = collections.Counter()
        script = API_SCRIPT.format(fmu_dir=args.fmu_dir)
        for _ in range(args.runs):
            p = subprocess.run([sys.executable, "-c", script], capture_output=True)
            api[p.returncode] += 1
    result = {
        "runs": args.runs,
        "cli_exit_codes": {str(k): v for k, v in sorted(cli.items())},
        "api_exit_codes": {str(k): v for k, v in sorted(api.items())},
        "seconds": round(time.perf_counter() - t0, 1),
    }
    if not args.json:
        print(f"glider-cosim run x{args.runs}: exit codes {result['cli_exit_codes']}")
        print(f"API script x{args.runs}: exit codes {result['api_exit_codes']}")
    print(json.dumps(result))
    sys.exit(0 if set(cli) == {0} and set(api) == {0} else 1)


if __name__ == "__main__":
    main()
