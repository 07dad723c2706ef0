"""The FMI call fuzz under valgrind memcheck: memory errors and leaks in our runtime.

Usage: python bench/fuzz_memcheck.py [--sequences N] [--seed S] [--fmu-dir DIR] [--json]

Runs tests/integration/fmi_fuzz.py (N random call sequences per FMU, the three glider
FMUs) under ``valgrind --tool=memcheck --leak-check=full`` with ``PYTHONMALLOC=malloc``
(so that Python's allocator does not hide errors), and counts the errors valgrind
reports: all of them, and those that are the runtime's (``binaries/linux64/*.so``): an
invalid access or use of an uninitialised value whose top frame is in the runtime or
whose uninitialised value was created there (``--track-origins=yes``), a leak whose
allocating caller is the runtime. Errors inside CPython on its own data (e.g. its integer
objects, a known false positive of memcheck) are counted among all errors only. Exit
status 0 if nothing was found in the runtime.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).parents[1]
FUZZ = ROOT / "tests" / "integration" / "fmi_fuzz.py"
NAMES = ("GliderPlant", "GliderObserver", "GliderController")


def parse(log: str) -> dict[str, object]:
    """Valgrind's report, split into error records; those touching our runtime counted."""
    records = re.split(r"\n==\d+== \n", log)
    kinds_all: collections.Counter = collections.Counter()
    kinds_ours: collections.Counter = collections.Counter()
    lost_ours = 0
    for rec in records:
        lines = [ln.split("== ", 1)[-1] for ln in rec.splitlines()]
        if not lines:
            continue
        head = lines[0]
        kind = None
        if head.startswith(("Invalid read", "Invalid write", "Invalid free")):
            kind = head.split(" of size")[0]
        elif "uninitialised" in head or head.startswith("Use of uninitialised"):
            kind = "uninitialised value"
        elif "definitely lost" in head:
            kind = "definitely lost"
        if kind is None:
            continue
        frames = [ln for ln in lines[1:] if ln.lstrip().startswith(("at 0x", "by 0x"))]
        origin_at = next((i for i, ln in enumerate(lines) if "was created by" in ln), None)
        main = frames if origin_at is None else [ln for ln in lines[1:origin_at] if "0x" in ln]
        origin = [] if origin_at is None else [ln for ln in lines[origin_at + 1 :] if "0x" in ln]

        def runtime(frame_lines: list[str]) -> bool:
            """The first frame that is no allocator is in our runtime."""
            for ln in frame_lines:
                if re.search(r"\b(malloc|calloc|realloc|strdup|free)\b", ln):
                    continue
                return bool(re.search(r"/binaries/linux64/\w+\.so", ln))
            return False

        ours = runtime(main) or runtime(origin)
        kinds_all[kind] += 1
        if ours:
            kinds_ours[kind] += 1
            if kind == "definitely lost":
                m = re.search(r"([\d,]+) bytes", head)
                lost_ours += int(m.group(1).replace(",", "")) if m else 0
    summary = re.findall(r"ERROR SUMMARY: (\d+) errors", log)
    return {
        "valgrind_error_summary": int(summary[-1]) if summary else None,
        "errors_all_by_kind": dict(kinds_all),
        "errors_in_runtime_by_kind": dict(kinds_ours),
        "definitely_lost_bytes_in_runtime": lost_ours,
    }


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    ap.add_argument("--sequences", type=int, default=300, help="sequences per FMU")
    ap.add_argument("--seed", type=int, default=20261201)
    ap.add_argument("--fmu-dir", default="fmus")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    args = ap.parse_args()
    valgrind = shutil.which("valgrind")
    if valgrind is None:
        sys.exit("bench/fuzz_memcheck.py: valgrind is not installed (apt-get install valgrind)")
    from glider_cosim.fmus.folders import build_all

    fmus = build_all(args.fmu_dir, only_stale=True)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "valgrind.log"
        cmd = [valgrind, "--tool=memcheck", "--leak-check=full", "--show-leak-kinds=definite",
               "--track-origins=yes", "--num-callers=30", f"--log-file={log}", sys.executable,
               str(FUZZ), str(args.seed), str(args.sequences),
               *(str(fmus[n]) for n in NAMES)]  # fmt: skip
        # one BLAS thread: OpenBLAS's worker threads spin while they wait, and valgrind
        # runs one thread at a time (a run was seen to crawl for 15 min in that wait)
        env = {**os.environ, "PYTHONMALLOC": "malloc", "OPENBLAS_NUM_THREADS": "1",
               "OMP_NUM_THREADS": "1"}  # fmt: skip
        p = subprocess.run(cmd, capture_output=True, text=True, env=env)
        done = p.stdout.rstrip().endswith("done")
        result = {"sequences_per_fmu": args.sequences, "seed": args.seed,
                  "fuzz_exit": p.returncode, "fuzz_done": done}  # fmt: skip
        result.update(parse(log.read_text(errors="replace")))
    result["seconds"] = round(time.perf_counter() - t0, 1)
    if not args.json:
        print(f"fuzz under valgrind: exit {p.returncode}, "
              f"{result['errors_in_runtime_by_kind'] or 'no'} errors in the runtime; "
              f"all errors: {result['errors_all_by_kind'] or 'none'}")  # fmt: skip
    print(json.dumps(result))
    clean = result["fuzz_done"] and not result["errors_in_runtime_by_kind"]
    sys.exit(0 if clean else 1)


if __name__ == "__main__":
    main()
