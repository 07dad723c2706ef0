"""The glider's closed loop as a master :class:`System`: which FMUs, how they connect,
what a scenario sets."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from ..components import COMPONENTS, component, every_run
from ..components import default_connections as registry_connections
from ..inputs.outputs import os_error
from ..inputs.text import quote
from ..master.errors import SystemSpecError
from ..master.spec import System
from .sampling import has_our_observer, with_sampling
from .scenario import Scenario, load_scenario

if TYPE_CHECKING:
    from ..master.cosimulation import CoSimulation

#: the default loop's instances (the registry's, in order)
DEFAULT_LOOP = tuple(c.name for c in every_run())


#: the inputs the loop drives itself (the disturbances: 0 unless a scenario sets them)
DISTURBANCE_INPUTS = tuple(f"{c.name}.{name}" for c in every_run() for name in c.driven)


def default_connections(feedback: str = "observer", observer: bool = True) -> list[tuple[str, str]]:
    """The default loop's connections, as the registry's components say (each
    ``component.toml``'s ``[inputs]``, and ``[state_feedback]`` under ``feedback =
    "state"``): plant -> observer -> controller -> plant (and -> observer)."""
    return registry_connections([n for n in DEFAULT_LOOP if observer or n != "observer"], feedback)


def scenario_connections(scenario: Scenario) -> list[tuple[str, str]]:
    """A scenario's connections: its components' defaults (those it adds included), each
    input the scenario's ``[connections]`` names taken from its source there instead."""
    conns = [
        (scenario.connections.get(dst, src), dst)
        for src, dst in registry_connections(scenario.instances(), scenario.feedback)
    ]
    given = {dst for _, dst in conns}
    conns += [(src, dst) for dst, src in scenario.connections.items() if dst not in given]
    return conns


def _loop_interface() -> dict[str, dict[str, tuple[str, str, str]]]:
    return {c.name: c.interface for c in COMPONENTS if c.interface}


#: where an input of a swapped-in FMU that the loop does not connect looks for an output
#: of the same name, first to last: the estimators' before the others (registry order)
_BY_NAME = tuple(c.name for c in sorted(every_run(), key=lambda c: not c.estimator))


def loop_wiring(
    connections: list[tuple[str, str]],
    variables: dict[str, dict[str, str]],
    model_names: dict[str, str],
    swapped_instances: set[str],
    driven: set[str],
) -> tuple[list[tuple[str, str]], list[str], list[str]]:
    """The loop's connections fitted to the FMUs swapped in, and one note per such FMU.

    What an FMU in place of our controller or estimator must have and may have is
    :data:`~glider_cosim.fmus.variables.LOOP_INTERFACE`: a connection to an optional
    input it lacks is dropped; each input it declares that no connection or driven value
    feeds is connected to the loop's output of the same name (the estimator's first,
    then the plant's), else left at its start value. Our FMUs (not swapped) are wired
    as they are.

    Parameters
    ----------
    connections : list of (source, target)
        ``"instance.variable"`` pairs (:func:`default_connections`).
    variables : dict
        Instance -> its variables' names -> causality (from the model descriptions).
    model_names : dict
        Instance -> model name, for the notes.
    swapped_instances : set of str
        The instances whose FMU the scenario swaps in (``[fmus]``).
    driven : set of str
        The ``"instance.variable"`` inputs the scenario drives (values, tables).

    Returns
    -------
    connections, notes, left
        The connections to make; one line per swapped FMU that was wired otherwise than
        ours (what was left unconnected, what was connected by name); the inputs
        (``"instance.variable"``) left at their start value, for the caller to drive.

    Raises
    ------
    SystemSpecError
        A swapped FMU lacks a variable the loop requires (named, with its causality and
        unit), or an output the other component reads.
    """
    loop = _loop_interface()
    interface = {inst: loop.get(inst, {}) for inst in swapped_instances}

    def who(inst: str) -> str:
        return f"{inst} ({quote(model_names.get(inst, inst))})"

    for inst in sorted(swapped_instances):
        lacks = [
            f"{name} ({caus}, {unit})"
            for name, (caus, unit, need) in interface[inst].items()
            if need == "required" and variables.get(inst, {}).get(name) != caus
        ]
        if lacks:
            raise SystemSpecError(
                f"{who(inst)} lacks what the loop requires of the {inst}: {', '.join(lacks)} "
                "(docs/reference/fmu-interfaces.md)"
            )
    skipped: dict[str, list[str]] = {}
    kept = []
    for src, dst in connections:
        inst, _, name = dst.partition(".")
        if inst in swapped_instances and name not in variables.get(inst, {}):
            if interface[inst].get(name, ("", "", "required"))[2] == "optional":
                skipped.setdefault(inst, []).append(f"{src} (no optional input {name})")
                continue
        kept.append((src, dst))
    for src, dst in kept:
        inst, _, name = src.partition(".")
        if interface.get(inst) and variables.get(inst, {}).get(name) != "output":
            caus, unit, _ = interface[inst].get(name, ("output", "", ""))
            raise SystemSpecError(
                f"{who(inst)} has no output {name}{f' ({unit})' if unit else ''}, which "
                f"{who(dst.partition('.')[0])} reads as {dst}: add the output, or swap in a "
                f"{dst.partition('.')[0]} without that input"
            )
    fed = {dst for _, dst in kept} | driven
    by_name: dict[str, list[str]] = {}
    left = []
    for inst in sorted(swapped_instances):
        for name, caus in variables.get(inst, {}).items():
            ref = f"{inst}.{name}"
            if caus != "input" or ref in fed:
                continue
            source = next(
                (f"{o}.{name}" for o in _BY_NAME
                 if o != inst and variables.get(o, {}).get(name) == "output"),
                None,
            )  # fmt: skip
            if source is None:
                left.append(ref)
                skipped.setdefault(inst, []).append(
                    f"input {name}, left at its start value (no output {name} in the loop)"
                )
            else:
                kept.append((source, ref))
                by_name.setdefault(inst, []).append(f"{source} -> {ref}")
    notes = []
    for inst in sorted(set(skipped) | set(by_name)):
        parts = []
        if skipped.get(inst):
            parts.append("not connected: " + "; ".join(skipped[inst]))
        if by_name.get(inst):
            parts.append("connected by name: " + ", ".join(by_name[inst]))
        notes.append(f"{who(inst)}: {'; '.join(parts)}")
    return kept, notes, left


def fit_swapped(sim: CoSimulation, swapped_instances: set[str]) -> list[str]:
    """Fit a loaded co-simulation's wiring to the FMUs swapped in (:func:`loop_wiring`):
    its connections replaced, the inputs nothing feeds driven at their start values;
    returns the notes (one line per swapped FMU wired otherwise than ours)."""
    mine = {inst for inst in swapped_instances if inst in sim.instances}
    if not mine:
        return []
    sim.system.connections, notes, left = loop_wiring(
        list(sim.system.connections),
        {n: {v.name: v.causality for v in i.md.modelVariables} for n, i in sim.instances.items()},
        {n: i.md.modelName for n, i in sim.instances.items()},
        mine,
        set(sim.system.driven) | set(sim.system.tables),
    )
    for ref in left:
        inst, _, name = ref.partition(".")
        sim.system.driven[ref] = float(sim.instances[inst].vars[name].start or 0.0)
    return notes


def swapped(scenario: Scenario) -> set[str]:
    """Our FMUs (model identifiers) a run of ``scenario`` does not take from the FMU
    folder: the instances its ``[fmus]`` table swaps (neither built nor checked there)."""
    return {component(inst).model for inst in scenario.fmus}


def swapped_in(scenario: str | Path | None) -> set[str]:
    """:func:`swapped` of a scenario as a command names it (a TOML file, a shipped name,
    None: the default); an SSP brings its own FMUs: none."""
    if scenario is not None and str(scenario).endswith((".ssp", ".ssd")):
        return set()
    return swapped(load_scenario(scenario))


def prepare_asked(
    fmu_dir: str | Path | None = None,
    flavor: str | None = None,
    fmi: int | None = None,
    *,
    overwrite_fmus: bool = False,
    host_only: bool = False,
    scenario: str | Path | None = None,
    swaps: bool = False,
) -> Path:
    """The FMU folder that ``--fmu-dir``, ``--flavor``, ``--fmi`` and ``--overwrite-fmus``
    ask for, built if missing or stale (:func:`glider_cosim.fmus.folders.prepare_fmus`).

    Parameters
    ----------
    fmu_dir : path, optional
        The folder (default: the per-user cache). One that does not exist gets a fresh
        set, with a note: a typo would build a whole new set.
    flavor, fmi : optional
        ``"python"``/``"native"``; 2 or 3 (default: what the folder holds).
    overwrite_fmus : bool
        Replace what the folder holds under our FMUs' names.
    host_only : bool
        The FMUs run on this machine alone (a run, a local sweep): the cache may serve a
        set with this machine's binary only.
    scenario : path or shipped name, optional
        With ``swaps`` and a folder given: the scenario whose ``[fmus]`` swaps in a
        user's FMU, which is then neither built nor checked there.
    swaps : bool
        Leave the scenario's swapped FMUs alone (see ``scenario``).

    Returns
    -------
    Path
        The folder of the FMUs.

    Raises
    ------
    UsageError
        The folder cannot be written (the message names ``--fmu-dir``).
    """
    from ..fmus import folders

    folder = Path(fmu_dir) if fmu_dir is not None else None
    if folder is not None and not folder.exists():
        note = f"--fmu-dir {quote(str(folder))} does not exist: a fresh set of FMUs is built there"
        logging.getLogger(__name__).warning(note)
    skip = swapped_in(scenario) if swaps and folder is not None else set()
    try:
        return folders.prepare_fmus(folder, flavor, fmi, host_only=host_only,
                                    overwrite=overwrite_fmus, skip=skip)  # fmt: skip
    except OSError as err:
        raise os_error(err, {"--fmu-dir": folder or folders.cache_root()}) from None


def system_for(scenario: Scenario, fmu_dir: Path, step: float | None = None) -> System:
    """The :class:`System` a scenario describes (FMUs from ``fmu_dir`` unless swapped),
    run at ``step`` (s; default the scenario's): the observer's ``f_sample`` follows it
    unless the scenario sets it (:func:`~glider_cosim.scenarios.sampling.with_sampling`)."""
    fmus = {
        inst: Path(scenario.fmus.get(inst, fmu_dir / f"{component(inst).model}.fmu"))
        for inst in scenario.instances()
    }
    for inst in scenario.components:  # added to the loop: it may have no native flavor
        c = component(inst)
        if inst not in scenario.fmus and not c.native and not fmus[inst].exists():
            raise SystemSpecError(
                f"{scenario.source}: component {quote(inst)} has no native flavor (no "
                f"c_sources in its component.toml), so {fmu_dir} has no {c.model}.fmu: "
                "expected --flavor python"
            )
    driven = dict.fromkeys(DISTURBANCE_INPUTS, 0.0)
    driven.update(scenario.inputs)
    return System(
        fmus=fmus,
        connections=scenario_connections(scenario),
        parameters=with_sampling(
            scenario.parameters,
            step if step is not None else scenario.step,
            scenario.source,
            has_our_observer(scenario),
        ),
        driven=driven,
        disturbances=list(scenario.disturbances),
        events=[type(e)(**{**e.__dict__}) for e in scenario.events],
        record=scenario.record,
    )
