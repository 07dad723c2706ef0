"""What the loop needs of a controller or estimator, checked on any FMU (``verify``).

The kit's reference cases compare an FMU with our laws' outputs: only a port of our
laws can match them. Any other controller or estimator is judged on what the closed
loop needs of it (:func:`loop_checks`):

``interface``
    the variables :data:`~glider_cosim.fmus.variables.LOOP_INTERFACE` requires, with
    their causality, and the unit each declares (none declared: taken as ours);
``initialization``
    its outputs can be read in Initialization Mode (the master reads them there);
``feedthrough`` (controller)
    ``delta_cmd`` follows a step of ``theta_g_hat`` at the same communication point, not
    one step late (:func:`~glider_cosim.runner.probe.probe_feedthrough`); an estimator's
    outputs are states of the end of the step and are not probed;
``closed loop``
    the default start (paper Sec. 3.3, -35 deg, 60 s) with the FMU in our loop settles.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..fmus.variables import LOOP_INTERFACE
from ..inputs.text import one_line, quote
from ..runner.probe import loop_values, probe_feedthrough
from .cases import VerifyInputError

#: the components a loop check applies to
LOOP_COMPONENTS = tuple(LOOP_INTERFACE)


@dataclass
class LoopCheck:
    """One check of what the loop needs: its name, pass or fail, and what it found."""

    name: str
    passed: bool
    detail: str

    def as_dict(self) -> dict[str, Any]:
        """Plain data (``verify --json``)."""
        return {"check": self.name, "result": "pass" if self.passed else "fail",
                "detail": self.detail}  # fmt: skip


def interface_check(md: Any, component: str, fmu_name: str) -> LoopCheck:
    """The loop's interface: required variables with their causality and unit.

    Raises
    ------
    VerifyInputError
        A required variable is missing or has another causality (named, one line).
    """
    have = {v.name: v for v in md.modelVariables}
    lacks, wrong, seen = [], [], []
    for name, (caus, unit, need) in LOOP_INTERFACE[component].items():
        v = have.get(name)
        if v is None or v.causality != caus:
            got = "" if v is None else f", is {v.causality}"
            if need == "required":
                lacks.append(f"{name} ({caus}, {unit}{got})")
            else:
                seen.append(f"{name}: absent ({need})")
            continue
        declared = getattr(v, "unit", None) or getattr(v, "declaredType", None)
        declared = getattr(declared, "unit", declared) if declared is not None else None
        if declared not in (None, "", unit):
            wrong.append(f"{name} in {declared}, expected {unit}")
        seen.append(f"{name} ({caus}, {declared or f'no unit: taken as {unit}'})")
    if lacks:
        raise VerifyInputError(
            f"FMU {quote(fmu_name)} ({md.modelName}) lacks what the loop requires of the "
            f"{component}: {', '.join(lacks)} (docs/reference/fmu-interfaces.md)"
        )
    if wrong:
        return LoopCheck("interface", False, "; ".join(wrong))
    return LoopCheck("interface", True, "; ".join(seen))


def initialization_check(path: Path, md: Any, component: str) -> LoopCheck:
    """The loop's outputs, read in Initialization Mode with the inputs at the steady glide."""
    from fmpy import extract, instantiate_fmu
    from fmpy.fmi1 import FMICallException

    names = [n for n, (c, _, _) in LOOP_INTERFACE[component].items() if c == "output"]
    have = {v.name: v for v in md.modelVariables}
    outs = [have[n] for n in names if n in have and have[n].causality == "output"]
    ins = [
        v for v in md.modelVariables
        if v.causality == "input" and v.type in ("Real", "Float64")
    ]  # fmt: skip
    held = loop_values()
    fmi3 = md.fmiVersion.startswith("3")
    with tempfile.TemporaryDirectory(prefix="glider_verify_") as tmp:
        fmu = None
        try:
            fmu = instantiate_fmu(extract(str(path), unzipdir=tmp), md, "CoSimulation")
            if fmi3:
                fmu.enterInitializationMode(startTime=0.0)
                set_values, get_values = fmu.setFloat64, fmu.getFloat64
            else:
                fmu.setupExperiment(startTime=0.0)
                fmu.enterInitializationMode()
                set_values, get_values = fmu.setReal, fmu.getReal
            for v in ins:
                set_values([v.valueReference], [held.get(v.name, float(v.start or 0.0))])
            values = get_values([v.valueReference for v in outs])
            fmu.exitInitializationMode()
        except (FMICallException, OSError, ValueError) as err:
            return LoopCheck("initialization", False, f"reading the outputs: {one_line(err)}")
        finally:
            if fmu is not None:
                try:
                    fmu.terminate()
                    fmu.freeInstance()
                except (FMICallException, OSError):
                    pass  # it failed above already: that is the finding
    bad = [f"{v.name} = {x!r}" for v, x in zip(outs, values) if not math.isfinite(x)]
    shown = ", ".join(f"{v.name} = {x:.6g}" for v, x in zip(outs, values))
    if bad:
        return LoopCheck("initialization", False, f"not finite: {', '.join(bad)}")
    return LoopCheck("initialization", True, f"readable in Initialization Mode: {shown}")


def feedthrough_check(path: Path) -> LoopCheck:
    """``delta_cmd`` follows ``theta_g_hat`` at the same point (not one step late)."""
    from ..master.errors import MasterError

    try:
        found = probe_feedthrough(path)
    except (ValueError, MasterError) as err:
        return LoopCheck("feedthrough", False, one_line(err))
    return LoopCheck("feedthrough", found.kind == "direct", found.describe())


def closed_loop_check(path: Path, component: str, fmu_dir: str | Path | None) -> LoopCheck:
    """The default start with the FMU in our loop (our plant and the other component):
    passes if the glide angle settles within the 60 s."""
    from ..master.errors import MasterError

    try:
        r = _run_default(path, component, fmu_dir)
    except (ValueError, MasterError) as err:
        return LoopCheck("closed loop", False, one_line(err))
    m = r.metrics
    if r.status != "ok":
        return LoopCheck("closed loop", False, f"the run ended: {r.message}")
    if m.get("outcome") == "settled":
        return LoopCheck(
            "closed loop", True,
            f"default start (-35 deg, 60 s): settled in {m['settling_time_s']:.3g} s",
        )  # fmt: skip
    return LoopCheck("closed loop", False, f"default start (-35 deg, 60 s): {m.get('outcome')}")


def _run_default(path: Path, component: str, fmu_dir: str | Path | None) -> Any:
    from ..runner.run import simulate
    from ..scenarios.scenario import load_scenario

    default = load_scenario("default")  # without our law's parameters (K_c, law)
    params = {k: v for k, v in default.parameters.items() if k != component}
    mine = dataclasses.replace(default, parameters=params, fmus={component: str(path)})
    return simulate(mine, None, fmu_dir=fmu_dir, plots=False)


def loop_checks(
    path: Path, md: Any, component: str, fmu_dir: str | Path | None = None
) -> list[LoopCheck]:
    """Every check of what the loop needs of ``component`` (module docstring), in order.

    Parameters
    ----------
    path : Path
        The FMU (read, never written).
    md : ModelDescription
        Its model description.
    component : {"controller", "observer"}
        What it stands in for.
    fmu_dir : path, optional
        Our FMUs for the closed loop (built there if missing or stale; default: the
        per-user cache).

    Returns
    -------
    list of LoopCheck
        Empty for a plant (the reference cases judge it).

    Raises
    ------
    VerifyInputError
        The FMU lacks what the loop requires (:func:`interface_check`).
    """
    from ..progress import Progress

    if component not in LOOP_COMPONENTS:
        return []
    checks = [interface_check(md, component, path.name)]
    steps: list[tuple[str, Callable[[], LoopCheck]]] = [
        ("initialization", lambda: initialization_check(path, md, component)),
        ("feedthrough", lambda: feedthrough_check(path)),
        ("closed loop: the default start", lambda: closed_loop_check(path, component, fmu_dir)),
    ]
    if component != "controller":
        del steps[1]
    with Progress(len(steps), "verify", f"verify {path.name}: what the loop needs") as bar:
        for label, check in steps:
            bar.step(label)
            checks.append(check())
    return checks


@dataclass
class LoopReport:
    """A :class:`~glider_cosim.verify.compare.Report` with the loop checks in front: its
    attributes are the report's; the verdict is the loop checks', and the reference
    cases' too for a port of our laws (an FMU that runs every case)."""

    report: Any
    loop: list[LoopCheck]

    @classmethod
    def of(cls, report: Any, loop: list[LoopCheck]) -> LoopReport:
        """``report`` judged with ``loop`` in front."""
        return cls(report, loop)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name in ("report", "loop"):  # unpickling: not set yet
            raise AttributeError(name)
        return getattr(self.report, name)

    @property
    def port(self) -> bool:
        """It runs every reference case: a port of our laws, held to their outputs."""
        return bool(self.report.results) and not self.report.skipped

    @property
    def passed(self) -> bool:
        """Every loop check passes (and, for a port, every reference case)."""
        ok = all(c.passed for c in self.loop)
        return ok and (self.report.passed if self.port else True)

    @property
    def exit_code(self) -> int:
        """``verify``'s exit code: 0 passed, 1 a check (or a port's case) failed."""
        return 0 if self.passed else 1

    def cases_note(self) -> str:
        """What the reference cases mean for this FMU."""
        if self.port:
            return "reference cases (it runs every case: a port of our laws, held to them)"
        return (
            "reference cases: they compare with our laws' outputs and apply only to ports "
            "of our laws; shown for information, not counted (one case: --case NAME)"
        )

    def table(self) -> str:
        """The header, the loop checks, then the reference cases' table and its count."""
        rows = [("loop check", "result", "detail")]
        rows += [(c.name, "pass" if c.passed else "FAIL", c.detail) for c in self.loop]
        w = [max(len(r[i]) for r in rows) for i in range(2)]
        lines = [self.report.header(), ""]
        lines += [f"{r[0].ljust(w[0])}  {r[1].ljust(w[1])}  {r[2]}".rstrip() for r in rows]
        cases = self.report.table().split("\n")[3:]  # the report's rows, without its header
        lines += ["", self.cases_note(), *cases]
        n_ok = sum(c.passed for c in self.loop)
        cases = self.report.results
        counted = (f"reference cases {sum(r.passed for r in cases)} of {len(cases)} pass"
                   if self.port else "reference cases not counted (not a port)")  # fmt: skip
        lines.append(
            f"{self.component} ({self.model_name}): loop checks {n_ok} of {len(self.loop)} "
            f"pass, {counted}: {'PASS' if self.passed else 'FAIL'}"
        )
        return "\n".join(lines)

    def as_dict(self) -> dict[str, Any]:
        """The report's data with ``loop_checks`` and ``port``; the verdict as above."""
        out = self.report.as_dict()
        out.update(passed=self.passed, exit_code=self.exit_code, port=self.port,
                   loop_checks=[c.as_dict() for c in self.loop])  # fmt: skip
        return out
