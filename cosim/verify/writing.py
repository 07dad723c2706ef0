"""Writing the verification kit: its references from our FMUs, and its FMI Cross-Check export."""

from __future__ import annotations

import re
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..fmus.files import package_version
from .cases import COMPONENTS, DEFAULT_CASE, case_names, kit_root, load_case
from .run import open_fmu, run_case


def write_references(fmu_dir: str | Path | None = None, dest: Path | None = None) -> list[Path]:
    """Run every case on our FMUs (built if missing or stale) and write ``_ref.csv`` and the
    ``DiscardTime`` of ``_ref.opt``.

    A case compares the outputs its ``_ref.csv`` names (its header line is kept: a new
    case may ship the header alone, e.g. ``time,V_hat,theta_g_hat`` for a case of the
    core interface); a case without one compares every output of our FMU.

    ``dest`` (default: the shipped kit) receives a complete copy of the kit with the new
    references; the shipped case definitions are read from the shipped kit.
    """
    from ..fmus.folders import build_all, fmu_folder

    fmus = build_all(fmu_folder(fmu_dir), only_stale=True)
    src = kit_root()
    dest = src if dest is None else Path(dest)
    written = []
    for component, model in COMPONENTS.items():
        (dest / component).mkdir(parents=True, exist_ok=True)
        if dest != src:
            for p in (src / component).iterdir():
                if p.is_file() and not p.name.endswith("_ref.csv"):
                    shutil.copyfile(p, dest / component / p.name)
        md = open_fmu(fmus[model])
        outputs = [v.name for v in md.modelVariables if v.causality == "output"]
        for name in case_names(component, src):
            c = load_case(component, name, src, with_reference=False)
            run = run_case(fmus[model], md, c, _compared(src / component, name) or outputs)
            if run.stop is not None and run.stop[0] != "discard":
                raise RuntimeError(f"{component} case {name}: {run.stop[2]}")
            ref = dest / component / f"{name}_ref.csv"
            ref.write_text(table_text(run.columns, run.data))
            opt = dest / component / f"{name}_ref.opt"
            lines = [ln for ln in opt.read_text().splitlines() if not ln.startswith("DiscardTime")]
            if run.stop is not None:
                lines.append(f"DiscardTime, {run.stop[1]!r}")
            opt.write_text("\n".join(lines) + "\n")
            written += [ref, opt]
    return written


def _compared(folder: Path, name: str) -> list[str]:
    """The outputs a case's ``_ref.csv`` names in its header ([] if it has none)."""
    path = folder / f"{name}_ref.csv"
    if not path.is_file():
        return []
    with open(path) as f:
        head = f.readline().strip().split(",")
    return head[1:] if head[0] == "time" else []


def table_text(columns: Sequence[str], data: np.ndarray) -> str:
    """A CSV table, every number in its shortest exact form."""
    lines = [",".join(columns)]
    lines += [",".join(repr(float(v)) for v in row) for row in data]
    return "\n".join(lines) + "\n"


def export(out: str | Path, fmu_dir: str | Path | None = None, platform: str = "linux64") -> Path:
    """Write the kit with our FMUs in the FMI Cross-Check layout; return the vendor folder.

    ``<out>/fmus/2.0/cs/<platform>/glider-cosim/<version>/<Model>/`` holds ``<Model>.fmu``
    and the default case as ``<Model>_in.csv``, ``<Model>_ref.csv``, ``<Model>_ref.opt``
    and ``ReadMe.txt``; every case (the default one too) is also in
    ``<Model>/cases/<case>/`` under the same file names, with ``<Model>_par.csv`` where the
    case sets parameters. Cross-check tools find one FMU per model folder and run the
    default case; the subfolders hold no FMU and are not picked up by them.
    """
    from ..fmus.folders import build_all, fmu_folder

    fmus = build_all(fmu_folder(fmu_dir), only_stale=True, host_only=False)  # handed on
    base = Path(out) / "fmus" / "2.0" / "cs" / platform / "glider-cosim" / package_version()
    for component, model in COMPONENTS.items():
        folder = base / model
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        shutil.copyfile(fmus[model], folder / f"{model}.fmu")
        src = kit_root() / component
        names = case_names(component)
        purposes = _purposes(src / "README.md")
        md = open_fmu(fmus[model])
        for name in names:
            sub = folder / "cases" / name
            sub.mkdir(parents=True)
            for suffix in ("_in.csv", "_ref.csv", "_ref.opt", "_par.csv"):
                if (src / f"{name}{suffix}").is_file():
                    shutil.copyfile(src / f"{name}{suffix}", sub / f"{model}{suffix}")
            (sub / "ReadMe.txt").write_text(_readme(model, component, name, purposes, md))
        default = DEFAULT_CASE[component]
        for suffix in ("_in.csv", "_ref.csv", "_ref.opt"):
            shutil.copyfile(
                folder / "cases" / default / f"{model}{suffix}", folder / f"{model}{suffix}"
            )
        text = _readme(model, component, default, purposes, md)
        others = ", ".join(n for n in names if n != default)
        text += (
            f"\nThe other cases of this model are in cases/<case>/ with the same file names "
            f"(run them with this FMU; set the parameters of {model}_par.csv where there is "
            f"one): {others}.\n"
        )
        (folder / "ReadMe.txt").write_text(text)
    return base


def _purposes(readme: Path) -> dict[str, str]:
    out = {}
    for line in readme.read_text().splitlines():
        m = re.match(r"\| `([a-z0-9_]+)` \| (.*?) \|", line)
        if m:
            out[m.group(1)] = m.group(2)
    return out


def _readme(model: str, component: str, name: str, purposes: dict[str, str], md: Any) -> str:
    case = load_case(component, name)
    lines = [
        f"{model} (glider-cosim {package_version()}), {component} case '{name}': "
        f"{purposes.get(name, '')}",
        "",
        f"Co-simulation from {case.start:g} s to {case.stop:g} s with a fixed communication "
        f"step of {case.step:g} s; the inputs of {model}_in.csv are held from each row's time "
        "to the next.",
        f"Comparison at every communication point: |y - y_ref| <= AbsTol + RelTol * |y_ref| "
        f"with RelTol = {case.rtol:g}, AbsTol = {case.atol:g} (SI units).",
    ]
    if case.parameters:
        pars = ", ".join(f"{k} = {v}" for k, v in case.parameters.items())
        lines.append(f"Parameters to set before initialisation ({model}_par.csv): {pars}.")
    else:
        lines.append("No parameters: the FMU's start values.")
    if case.discard_time is not None:
        lines.append(
            f"Expected end: the FMU returns fmi2Discard from the doStep that starts at "
            f"t = {case.discard_time:g} s (DiscardTime in {model}_ref.opt; within one step)."
        )
    feedthrough = [
        u.variable.name
        for u in md.outputs
        if u.dependencies is None or any(d.causality == "input" for d in u.dependencies)
    ]
    if feedthrough:
        lines.append(
            f"{', '.join(feedthrough)} depends directly on the inputs: the reference records it "
            "after the inputs of the same communication point are set (row k uses the inputs "
            "of row k). A tool that records outputs before it sets the inputs of the point "
            "(e.g. fmpy's simulate_fmu) shows the same values one row later."
        )
    lines.append("Checked with: glider-cosim verify " + f"{model}.fmu --case {name}")
    return "\n".join(lines) + "\n"
