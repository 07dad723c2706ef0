"""A plain fmpy script with our three FMUs exits normally, every time (no abort at exit).

pythonfmu's binary aborted about 1 such exit in 20 ("corrupted double-linked list"); our
runtime never finalizes an interpreter and holds exactly the references it takes. 30 runs
here (bench/exit_stress.py runs 500), half of them without terminate/free.
"""

from __future__ import annotations

import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration
SCRIPT = Path(__file__).parents[2] / "bench" / "plain_fmpy_script.py"


def test_plain_fmpy_script_exits_0_in_30_of_30_runs(fmu_dir):
    cmds = [[sys.executable, str(SCRIPT), str(fmu_dir), *(["--no-free"] if i % 2 else [])]
            for i in range(30)]  # fmt: skip

    def run(cmd):
        return subprocess.run(cmd, capture_output=True, text=True, timeout=300)

    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(run, cmds))
    failed = [(r.returncode, r.stderr[-500:]) for r in results if r.returncode != 0]
    assert not failed, failed
