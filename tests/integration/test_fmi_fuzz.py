"""300 random FMI call sequences per FMU, in one process: statuses only, never a crash
(FMI 2.0 through fmi_fuzz.py, FMI 3.0 through fmi3_fuzz.py).

The sequences come from tests/integration/fmi_fuzz.py with a fixed seed; a failure
prints the FMU, sequence and seed to replay with
``python tests/integration/fmi_fuzz.py SEED 300 FMU``.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration
FUZZ = Path(__file__).parent / "fmi_fuzz.py"
SEED = 20261201


def run_fuzz(script: Path, fmus: list[Path], error: str) -> None:
    """``script SEED 300 FMU...``: every sequence run and every call a status, with real
    steps and real refusals (``error``, the standard's error status) on each FMU."""
    p = subprocess.run([sys.executable, str(script), str(SEED), "300", *map(str, fmus)],
                       capture_output=True, text=True, timeout=600)  # fmt: skip
    lines = p.stdout.splitlines()
    last = next((ln for ln in reversed(lines) if ln.startswith(("sequence", "FAILED"))), "")
    assert p.returncode == 0, f"exit {p.returncode} at '{last}': {p.stderr[-2000:]}"
    assert lines[-1] == "done"
    for fmu in fmus:
        m = re.search(rf"^{fmu.stem}: (\d+) calls, (\d+) steps OK, (\d+) {error}$", p.stdout,
                      re.MULTILINE)  # fmt: skip
        assert m, p.stdout[-500:]
        calls, steps, errors = map(int, m.groups())
        assert calls > 3000 and steps > 10 and errors > 1000  # real steps, real refusals
        assert sum(ln.startswith(f"sequence {fmu.stem} ") for ln in lines) == 300


def test_random_call_sequences_return_statuses_and_never_crash(flavor_dir, test_fmus):
    fmus = [flavor_dir / f"{n}.fmu" for n in ("GliderPlant", "GliderObserver", "GliderController")]
    fmus.append(test_fmus["RuntimeTestProbe"])
    run_fuzz(FUZZ, fmus, "fmi2Error")


FUZZ3 = Path(__file__).parent / "fmi3_fuzz.py"


@pytest.mark.parametrize("flavor", ["python", "native"])
def test_random_fmi3_call_sequences_return_statuses_and_never_crash(fmi3_dirs, flavor):
    fmus = [fmi3_dirs[flavor] / f"{n}.fmu" for n in ("GliderPlant", "GliderObserver",
                                                     "GliderController")]  # fmt: skip
    run_fuzz(FUZZ3, fmus, "fmi3Error")
