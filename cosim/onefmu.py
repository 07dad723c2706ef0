"""One-FMU export of the closed loop (``glider-cosim export-fmu``): plant, observer and
controller combined into a single FMI 2.0 co-simulation FMU with fmu-manipulation-toolbox's
``fmucontainer``, for tools that take one FMU.

The container steps the three FMUs at 0.02 s (sequentially, plant, observer, controller)
and exposes the contract's outputs as ``plant.theta_g`` and so on, the disturbance
inputs ``plant.F_x``, ``plant.F_z``, ``plant.M_y``, and the scenario's parameter values as
start values.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from fmpy import read_model_description

from .runner import DISTURBANCE_INPUTS, FMU_NAMES, default_connections
from .scenario import Scenario, load_scenario


class ExportError(RuntimeError):
    """fmucontainer failed (its last message is included)."""


def container_description(scenario: Scenario, fmu_dir: Path) -> dict:
    """fmucontainer's JSON description of the closed loop."""
    insts = {i: f"{n}.fmu" for i, n in FMU_NAMES.items() if scenario.observer or i != "observer"}
    links = []
    for src, dst in default_connections(scenario.feedback, scenario.observer):
        (si, sv), (di, dv) = src.split(".", 1), dst.split(".", 1)
        links.append([insts[si], sv, insts[di], dv])
    outputs = []
    for inst, fname in insts.items():
        md = read_model_description(str(fmu_dir / fname))
        outputs += [[fname, v.name, f"{inst}.{v.name}"] for v in md.modelVariables
                    if v.causality == "output"]  # fmt: skip
    starts = [[insts[i], k, v] for i, ps in scenario.parameters.items() for k, v in ps.items()]
    inputs = [[ref, insts["plant"], ref.split(".", 1)[1]] for ref in DISTURBANCE_INPUTS]
    return {
        "name": "GliderLoop.fmu",
        "step_size": scenario.step,
        "sequential": True,
        "fmu": list(insts.values()),
        "input": inputs,
        "output": outputs,
        "link": links,
        "start": starts,
    }


def export_one_fmu(
    out_path: str | Path, scenario: Scenario | str | None = None, fmu_dir: str | Path = "fmus"
) -> Path:
    """Build the closed loop as one FMU at ``out_path`` and return its path."""
    from .build import build_all

    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if scenario.events or scenario.disturbances or scenario.fmus:
        raise ExportError(f"{scenario.source}: events, disturbances and swapped FMUs cannot "
                          "be exported into one FMU")  # fmt: skip
    fmus = build_all(fmu_dir, only_stale=True)
    out = Path(out_path)
    with tempfile.TemporaryDirectory(prefix="glider_container_") as tmp:
        work = Path(tmp)
        for f in fmus.values():
            shutil.copy2(f, work / f.name)
        spec = container_description(scenario, work)
        (work / "GliderLoop.json").write_text(json.dumps(spec, indent=1))
        exe = Path(sys.executable).with_name("fmucontainer")
        cmd = [
            str(exe) if exe.exists() else "fmucontainer",
            "-container",
            f"GliderLoop.json:{scenario.step}",
            "-fmu-directory",
            str(work),
            "-sequential",
        ]
        p = subprocess.run(cmd, cwd=work, capture_output=True, text=True)  # fmt: skip
        built = work / "GliderLoop.fmu"
        if p.returncode != 0 or not built.exists():
            last = (p.stderr or p.stdout).strip().splitlines()[-1:] or ["no output"]
            raise ExportError(f"fmucontainer failed: {last[0]}")
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(built, out)
    return out
