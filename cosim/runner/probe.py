"""Probes of a controller FMU swapped into the loop: is its output computed from its input
when read, or one communication step late (set in ``doStep``)?

The probe runs the FMU alone, twice, for a few steps with our master: once with its
input held, once with the input stepped at one communication point. Where the two
outputs first differ tells how the output depends on the input: at that point (direct
feedthrough, what the loop's Gauss-Seidel exchange expects of a controller), one step
later (the usual pythonfmu pattern of setting the output in ``do_step``: a silent 20 ms
delay in the loop), or not within the probe.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

from ..inputs.text import quote

#: the fix, named wherever a one-step-late output is
LATE_FIX = (
    "compute the output from the inputs when it is read (in the getter; a C FMU in "
    "fmi2GetReal), not in do_step (docs/how-to/write-a-controller.md)"
)

#: the step of the input the probe makes (rad: about 1.1 deg on theta_g_hat)
PROBE_STEP = 0.02

#: communication points of each probe run; the input steps at the third
_POINTS = 6
_AT = 2


@dataclass
class Feedthrough:
    """How an output responds to a step of an input (:func:`probe_feedthrough`)."""

    output: str
    input: str
    #: ``"direct"`` (same point), ``"late"`` (one step later), ``"none"`` (no response
    #: within the probe)
    kind: str
    step: float

    def describe(self, who: str = "") -> str:
        """One line: what the probe found, and for a late output, the fix."""
        head = f"{who + ': ' if who else ''}{self.output}"
        if self.kind == "direct":
            return f"{head} responds to {self.input} at the same communication point"
        if self.kind == "late":
            return f"{head} responds to {self.input} one step ({self.step:g} s) late: {LATE_FIX}"
        return (
            f"{head} did not respond to a {PROBE_STEP:g} step of {self.input} within "
            f"{_POINTS - _AT - 1} steps"
        )


def loop_values() -> dict[str, float]:
    """The loop's inputs at the paper's steady glide (SI units): where the probe holds
    the inputs it does not step."""
    eq = equilibrium(GliderParams())
    return {"V_hat": eq.V, "theta_g_hat": eq.theta_g, "theta_meas": eq.theta_g + eq.alpha}


def probe_feedthrough(
    fmu: str | Path,
    output: str = "delta_cmd",
    input: str = "theta_g_hat",
    step: float = 0.02,
) -> Feedthrough:
    """Where ``output`` of ``fmu`` first responds to a step of ``input``.

    Parameters
    ----------
    fmu : path
        An FMI 2.0 or 3.0 co-simulation FMU with the real input and output named (it is
        read, never written).
    output, input : str
        The variables probed.
    step : float
        The communication step (s).

    Returns
    -------
    Feedthrough
        ``kind`` ``"direct"``, ``"late"`` or ``"none"``.

    Raises
    ------
    ValueError
        The FMU lacks ``input`` or ``output`` (named in one line).
    glider_cosim.master.MasterError
        The FMU fails in the probe.
    """
    from ..inputs.archives import read_fmu
    from ..master.cosimulation import CoSimulation
    from ..master.spec import System
    from .recorders import ArrayRecorder

    md = read_fmu(Path(fmu), None)
    have = {v.name: v for v in md.modelVariables}
    for name, caus in ((input, "input"), (output, "output")):
        if name not in have or have[name].causality != caus:
            raise ValueError(f"FMU {quote(Path(fmu).name)} has no {caus} {quote(name)}")
    held = loop_values()
    driven = {
        f"fmu.{v.name}": float(held.get(v.name, float(v.start or 0.0)))
        for v in md.modelVariables
        if v.causality == "input" and v.name != input and v.type in ("Real", "Float64")
    }
    base = held.get(input, float(have[input].start or 0.0))
    times = [k * step for k in range(_POINTS)]
    runs = []
    for jump in (0.0, PROBE_STEP):
        values = [base + (jump if k >= _AT else 0.0) for k in range(_POINTS)]
        system = System(
            fmus={"fmu": Path(fmu)},
            connections=[],
            parameters={"fmu": {}},
            driven=dict(driven),
            tables={f"fmu.{input}": (times, values)},
            record=[f"fmu.{output}"],
        )
        sim = CoSimulation(system, step=step)
        rec = ArrayRecorder()
        try:
            sim.run((_POINTS - 1) * step, rec)
        finally:
            sim.close()
        runs.append(rec.array(2)[:, 1])
    a, b = runs
    differ = [k for k in range(min(len(a), len(b))) if abs(a[k] - b[k]) > 1e-12]
    kind = "none" if not differ else "direct" if differ[0] <= _AT else "late"
    if differ and differ[0] > _AT + 1:
        kind = "none"
    return Feedthrough(output, input, kind, step)


def late_notes(fmus: dict[str, Path]) -> list[str]:
    """A line for a swapped-in controller whose ``delta_cmd`` is one step late (``run``
    logs it); nothing for a direct one, our FMUs or an FMU the probe cannot run (the run
    itself then says what fails). ``fmus``: the scenario's ``[fmus]`` (instance -> path)."""
    from ..master.errors import MasterError

    path = fmus.get("controller")
    if path is None:
        return []
    try:
        found = probe_feedthrough(path)
    except (MasterError, ValueError):
        return []
    return [found.describe(f"controller ({Path(path).name})")] if found.kind == "late" else []
