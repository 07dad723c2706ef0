"""Benchmark: instructions per FMI call of the Python flavor, counted by callgrind.

Usage: python bench/call_instructions.py [--fmu-dir fmus] [--calls N] [--json]
The C timer of ``bench/fmu_step.py`` (no Python in the host: the runtime starts it) runs
each FMU under ``valgrind --tool=callgrind`` twice, with N and with 0 timed calls of each
of fmi2DoStep, fmi2GetReal and fmi2SetReal (the same start-up and 200 warm-up steps),
counting only inside those three functions (``--toggle-collect``); the difference over N
is what one doStep + getReal + setReal costs, in instructions: the runtime, the slave's
Python and the model.
Unlike wall time, the count does not depend on what else the machine does, so two
builds (``--fmu-dir`` of each) compare to the instruction.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

from _common import emit, parse_args
from fmpy import read_model_description
from fmu_step import INPUTS, READ, compile_timer

from glider_cosim.master.instance import _extracted


def instructions(timer: Path, fmu: Path, n: int, out: Path) -> int:
    """Instructions (callgrind's Ir) of one timer run with ``n`` calls of each kind."""
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    name = md.modelName
    get_arg = ",".join(str(vr[k]) for k in READ[name])
    set_arg = ",".join(f"{vr[k]}={v!r}" for k, v in INPUTS[name].items())
    log = out / f"{name}-{n}.callgrind"
    collect = [f"--toggle-collect={f}" for f in ("fmi2DoStep", "fmi2GetReal", "fmi2SetReal")]
    argv = ["valgrind", "--tool=callgrind", *collect, f"--callgrind-out-file={log}",
            str(timer), _extracted(fmu), md.coSimulation.modelIdentifier, str(n), get_arg,
            set_arg]  # fmt: skip
    p = subprocess.run(argv, capture_output=True, text=True, timeout=1200,
                       env={"PATH": "/usr/bin:/bin", "PYTHONHASHSEED": "0"})  # fmt: skip
    if p.returncode != 0:
        raise SystemExit(f"callgrind run failed ({p.returncode}): {p.stderr[-500:]}")
    m = re.search(r"Collected\s*:\s*(\d+)", p.stderr)
    if m is None:
        raise SystemExit("callgrind printed no instruction count")
    return int(m.group(1))


def main() -> None:
    args = parse_args(__doc__, ("--calls", {"type": int, "default": 2000}))
    if shutil.which("valgrind") is None:
        raise SystemExit("bench/call_instructions.py: valgrind is not installed")
    result: dict[str, object] = {}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        timer = compile_timer(out)
        for fmu in sorted(Path(args.fmu_dir).glob("Glider*.fmu")):
            base = instructions(timer, fmu, 0, out)
            full = instructions(timer, fmu, args.calls, out)
            result[fmu.stem] = round((full - base) / args.calls)
    result["unit"] = "instructions per doStep + getReal + setReal"
    emit(result, args.json)


if __name__ == "__main__":
    main()
