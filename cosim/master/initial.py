"""Initialization Mode as the standard's importers run it: the inputs the master sets there.

Every instance has entered Initialization Mode (set up, parameters set). The master then
sets the inputs there as fmpy's ``simulate_fmu``, fmusim and fmu-manipulation-toolbox's
container do: the driven ones at ``t0``, then each connected one from its source, in the
order of the sources' ``<InitialUnknowns>`` dependencies
(:func:`~glider_cosim.master.plan.initialization_order`), and every instance exits. An FMU
computes the values got there from what is set so far, the values it has after Exit (ours
do, bit for bit): so the first row is the one those importers give
(docs/explanation/co-simulation.md).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .errors import SystemSpecError
from .instance import Instance


class InitialInputs:
    """Initialization Mode of a :class:`~glider_cosim.master.cosimulation.CoSimulation`:
    a mixin, as :class:`~glider_cosim.master.driven.DrivenInputs` is, using its
    instances, ``_init_order`` (from its plan), start time and FMI calls."""

    instances: dict[str, Instance]
    t0: float
    _init_order: list[tuple[str, str]]
    _call: Callable[..., Any]
    _resolve: Callable[..., Any]
    _set_value: Callable[..., None]
    _drive: Callable[[float], None]

    def _initialization_mode(self) -> None:
        """Set the inputs in Initialization Mode, then exit it, every instance.

        An external endpoint answers only after Exit (its START carries the parameters
        and the inputs set so far): it exits when one of its outputs is first needed;
        an input set after that reaches it at the start time's exchange."""
        exited: set[str] = set()
        self._drive(self.t0)
        for dst, src in self._init_order:
            si, sv = self._resolve(src)
            di, dv = self._resolve(dst)
            if not si.outputs_before_exit and si.name not in exited:
                self._exit(si)
                exited.add(si.name)
            self._set_value(di, dv.name, self._get_initial(si, sv.name))
        for inst in self.instances.values():
            if inst.name not in exited:
                self._exit(inst)

    def _exit(self, inst: Instance) -> None:
        self._call(inst, "fmi2ExitInitializationMode", inst.slave.exitInitializationMode)

    def _get_initial(self, inst: Instance, name: str) -> Any:
        """An output's value in Initialization Mode (an FMU's error names the mode)."""
        v = inst.vars[name]
        s = inst.slave
        get = {"Real": s.getReal, "Integer": s.getInteger, "Boolean": s.getBoolean}.get(v.type)
        if get is None:
            raise SystemSpecError(f"{inst.name}.{name}: type {v.type} cannot be read")
        call = f"fmi2Get{v.type}({name}) in Initialization Mode"
        return self._call(inst, call, get, [v.valueReference])[0]
