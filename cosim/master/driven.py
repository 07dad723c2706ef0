"""Driven inputs, disturbances and events: what the master sets itself at each point."""

from __future__ import annotations

import bisect
from collections.abc import Callable
from typing import Any

from .instance import Instance
from .plan import Group, driven_refs
from .spec import System, VarRef


class DrivenInputs:
    """The inputs a :class:`~glider_cosim.master.cosimulation.CoSimulation` sets at every
    communication point: driven inputs (a constant, plus disturbances and a table) and
    the actions of events.

    A mixin of the co-simulation, so that the per-step calls and flags stay on one object
    (no lookup more per step); it uses the co-simulation's :attr:`system`,
    :attr:`values`, ``_driven`` groups (:func:`~glider_cosim.master.plan.plan_exchange`)
    and its FMI calls ``_call``, ``_resolve`` and ``_set_value``.
    """

    system: System
    values: dict[str, float]
    _driven: list[tuple[Instance, Group, list[str]]]
    _driven_base: dict[str, float]
    _driven_last: dict[int, list[float] | None]
    _pending_events: int
    _drive_static: bool
    _drive_done: bool
    _call: Callable[..., Any]
    _resolve: Callable[..., Any]
    _set_value: Callable[..., None]

    def _driven_refs(self) -> list[str]:
        return driven_refs(self.system)

    def _reset_inputs(self) -> None:
        """Events not fired, driven inputs at their base values, to be set at the next
        point (a fresh or reset run)."""
        for ev in self.system.events:
            ev.fired_at, ev.applied = None, False
        self._driven_base = {r: float(self.system.driven.get(r, 0.0)) for r in self._driven_refs()}
        self._pending_events = len(self.system.events)
        self._drive_static = not self.system.disturbances and not self.system.tables
        self._drive_done = False
        self._driven_last = dict.fromkeys(range(len(self._driven)))

    def _drive(self, t: float) -> None:
        if self._drive_static and self._drive_done:
            return  # constant inputs already set: the FMUs hold them
        self._drive_done = True
        tables = self.system.tables
        disturbances = self.system.disturbances
        for j, (inst, g, refs) in enumerate(self._driven):
            new = []
            for ref in refs:
                value = self._driven_base[ref]
                for d in disturbances:
                    if d.target == ref:
                        value += d.at(t)
                if ref in tables:
                    times, values = tables[ref]
                    value += values[max(bisect.bisect_right(times, t + 1e-9) - 1, 0)]
                new.append(value)
            if new == self._driven_last[j]:
                continue  # unchanged since the last call: the FMU holds its inputs
            self._call(inst, "fmi2SetReal", inst.slave.setReal, list(g.vr), new)
            self._driven_last[j] = new

    def _events(self, t: float) -> bool:
        if not self._pending_events:
            return False
        changed = False
        for ev in self.system.events:
            if ev.applied:
                continue
            if ev.fired_at is None:
                value = t if ev.variable == "time" else self.values[ev.variable]
                if ev.holds(value):
                    ev.fired_at = t
            if ev.fired_at is not None and t >= ev.fired_at + ev.delay - 1e-9:
                for target, value in ev.actions.items():
                    inst, _ = self._resolve(target)
                    if target in self._driven_base:
                        self._driven_base[target] = float(value)
                        self._drive_done = False
                    else:
                        self._set_value(inst, VarRef.parse(target).variable, value)
                ev.applied = True
                changed = True
                self._pending_events -= 1
        return changed
