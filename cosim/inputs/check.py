"""A run's values checked before any FMU is instantiated.

:func:`check_system_values` checks every parameter, constant input, event threshold and
event action of a loaded :class:`~glider_cosim.master.CoSimulation` against the model
descriptions (variable exists and can be set, FMI type, integer range, unit).
:func:`check_ranges` checks the values meant for our own FMUs against their parameter
tables (the valid ranges the FMUs themselves enforce at initialisation), so that the CLI
refuses them in one line instead of starting a run that fails.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable
from typing import Any

from ..components import COMPONENTS, by_model
from .text import did_you_mean, quote
from .values import (
    Quantity,
    ValueCheckError,
    check_declared_unit,
    check_unit,
    check_value,
    unit_of,
)

#: the slave class holding each of our FMUs' variable table (the component registry's)
SLAVES = {c.name: c.slave for c in COMPONENTS}
Origin = Callable[[str], str]


def _settable(inst: Any, name: str, where: str) -> Any:
    v = inst.vars.get(name)
    if v is None:
        raise ValueCheckError(
            f"{where}: instance {inst.name} ({inst.md.modelName}) has no variable {quote(name)}"
            + did_you_mean(name, _settable_names(inst))
        )
    if v.causality not in ("parameter", "input") or v.variability == "constant":
        raise ValueCheckError(
            f"{where}: {inst.name}.{name} is a {v.variability} {v.causality}: it cannot be set"
        )
    return v


def _settable_names(inst: Any) -> list[str]:
    return [n for n, v in inst.vars.items()
            if v.causality in ("parameter", "input") and v.variability != "constant"]  # fmt: skip


def check_system_values(sim: Any, origin: Origin) -> None:
    """Check (and convert in place) the values a loaded co-simulation will set.

    Parameters
    ----------
    sim : glider_cosim.master.CoSimulation
        After :meth:`~glider_cosim.master.CoSimulation.load` (model descriptions read,
        nothing instantiated).
    origin : callable
        ``"instance.variable"`` -> where the value came from, for messages (the file and
        key, ``--set ...``, the SSP element).

    Raises
    ------
    ValueCheckError
        The first value that does not fit its variable.
    """
    system = sim.system
    for inst_name, params in system.parameters.items():
        inst = sim.instances.get(inst_name)
        if inst is None:
            raise ValueCheckError(
                f"{origin(inst_name)}: no instance {quote(inst_name)} "
                f"(instances: {', '.join(sim.instances)})" + did_you_mean(inst_name, sim.instances)
            )
        for name in list(params):
            where = origin(f"{inst_name}.{name}")
            v = _settable(inst, name, where)
            params[name] = check_value(params[name], inst.md, v, where)
    for ref, value in system.driven.items():
        inst_name, _, name = ref.partition(".")
        inst = sim.instances.get(inst_name)
        v = inst.vars.get(name) if inst is not None else None
        if v is not None:  # (a missing one is named by the wiring check)
            system.driven[ref] = float(check_value(value, inst.md, v, origin(ref)))
    for i, ev in enumerate(system.events):
        where = origin(f"event[{i}]")
        if isinstance(ev.threshold, bool) or not math.isfinite(float(ev.threshold)):
            raise ValueCheckError(
                f"{where}.when: threshold {quote(ev.threshold)} is invalid: expected a finite "
                "number"
            )
        if isinstance(ev.threshold, Quantity):
            inst_name, _, name = ev.variable.partition(".")
            inst = sim.instances.get(inst_name)
            v = inst.vars.get(name) if inst is not None and name else None
            if v is None or v.type != "Real":
                unit = "s" if ev.variable == "time" else (unit_of(v) if v is not None else "?")
                raise ValueCheckError(
                    f"{where}.when: {quote(ev.threshold.text)} is invalid: {ev.variable} is "
                    f"in {unit}: expected a plain number"
                )
            check_unit(ev.threshold, inst.md, v, f"{where}.when")
        for target in list(ev.actions):
            inst_name, _, name = target.partition(".")
            inst = sim.instances.get(inst_name)
            twhere = f"{where}.set.{target}"
            if inst is None:
                raise ValueCheckError(
                    f"{twhere}: no instance {quote(inst_name)} (instances: "
                    f"{', '.join(sim.instances)})" + did_you_mean(inst_name, sim.instances)
                )
            v = _settable(inst, name, twhere)
            ev.actions[target] = check_value(ev.actions[target], inst.md, v, twhere)


def _table(inst: str) -> dict[str, Any]:
    """The slave's ``VARIABLES`` from ``glider_<component>.variables`` (the slave's own
    table, read without importing pythonfmu and the slave: 25-35 ms of a run, issue 48)."""
    module = SLAVES[inst].partition(".")[0] + ".variables"
    return {v.name: v for v in importlib.import_module(module).VARIABLES}


def our_table(inst: str) -> dict[str, Any]:
    """Variable name -> its ``Var`` (unit, range) in our FMU ``inst`` (KeyError if none)."""
    return _table(inst)


def check_ranges(
    parameters: dict[str, dict[str, Any]],
    origin: Origin,
    swapped: set[str] | frozenset[str] = frozenset(),
    events: list[Any] | None = None,
    kinds: dict[str, str] | None = None,
) -> None:
    """Check values for our own FMUs against their parameter tables' valid ranges.

    Parameters
    ----------
    parameters : dict
        ``{instance: {name: value}}``; instances in ``swapped`` (another FMU) and
        values that are not plain numbers (the type check reports those) are skipped.
    origin : callable
        As in :func:`check_system_values`.
    swapped : set of str
        Instances that are not our FMUs.
    events : list of Event, optional
        Their actions on our FMUs are checked too.
    kinds : dict, optional
        Instance -> which of our FMUs it is (``"plant"``, ``"observer"``,
        ``"controller"``); default: the instances of those names.

    Raises
    ------
    ValueCheckError
        A value outside its range, or plant constants without a steady glide.
    """
    from glider_plant.params import GliderParams, ParameterError

    if kinds is None:
        kinds = {i: i for i in SLAVES}
    kinds = {i: k for i, k in kinds.items() if i not in swapped and k in SLAVES}
    checks = [(inst, name, value, origin(f"{inst}.{name}"))
              for inst, params in parameters.items() for name, value in params.items()]  # fmt: skip
    for i, ev in enumerate(events or ()):
        for target, value in ev.actions.items():
            inst, _, name = target.partition(".")
            checks.append((inst, name, value, f"{origin(f'event[{i}]')}.set.{target}"))
    tables: dict[str, dict[str, Any]] = {}
    for inst, name, value, where in checks:
        if inst not in kinds:
            continue
        table = tables.setdefault(kinds[inst], _table(kinds[inst]))
        spec = table.get(name)
        if spec is None or isinstance(value, bool):
            continue
        check_declared_unit(value, name, spec.unit, where)  # a unit error before a range's
        if spec.valid is None or not isinstance(value, int | float):
            continue
        try:
            v = float(value)
        except OverflowError:
            v = math.inf
        if spec.type == "Integer" and not float(v).is_integer():
            continue  # not an integer: the type check says so
        if not spec.valid.contains(v):
            shown = quote(value.text if isinstance(value, Quantity) else value)
            if spec.type == "Integer":
                r = spec.valid
                expected = f"an integer in [{r.low:.0f}, {r.high:.0f}]"
            else:
                unit = "" if spec.unit == "1" else f" ({spec.unit})"
                expected = spec.valid.describe() + unit
            raise ValueCheckError(f"{where}: {shown} is invalid: expected {expected}")
    for inst, kind in kinds.items():
        if kind not in ("plant", "controller") or inst not in parameters:
            continue
        try:
            GliderParams.from_mapping(
                {k: v for k, v in parameters[inst].items() if isinstance(v, int | float)}
            )
        except ParameterError as err:
            raise ValueCheckError(f"{origin(inst)}: {err}") from None
        except (TypeError, OverflowError):
            continue
        if kind != "plant":
            continue
        plant = parameters[inst]
        if "delta_0" in plant or "delta_max" in plant:
            table = tables.setdefault("plant", _table("plant"))
            d0 = plant.get("delta_0", table["delta_0"].start)
            dmax = plant.get("delta_max", table["delta_max"].start)
            if isinstance(d0, int | float) and isinstance(dmax, int | float) and abs(d0) > dmax:
                raise ValueCheckError(
                    f"{origin(f'{inst}.delta_0')}: {quote(d0)} is invalid: expected "
                    f"|delta_0| <= delta_max = {dmax:g} rad"
                )


def our_kinds(fmus: dict[str, Any]) -> dict[str, str]:
    """Instance -> ``"plant"``/``"observer"``/``"controller"`` for the FMUs that are ours
    (by model name and pythonfmu generation tool), e.g. the components of our SSP."""
    from .archives import InputFileError, read_description

    kinds = {}
    for inst, path in fmus.items():
        try:
            md = read_description(path)
        except InputFileError:  # an unreadable FMU is not ours
            continue
        ours = by_model(md.modelName)
        if ours is not None and str(md.generationTool or "").startswith("PythonFMU"):
            kinds[inst] = ours.name
    return kinds
