"""The co-simulation master's run loop: CoSimulation loads, initialises and steps a System.

It runs FMI 2.0 and FMI 3.0 co-simulation FMUs at a fixed step, read by
``fmpy.read_model_description``: FMI 2.0 instances on fmpy's ``FMU2Slave``, FMI 3.0 ones
on fmpy's ``FMU3Slave`` behind the same FMI 2.0-named calls
(:mod:`glider_cosim.master.fmi3`: Float64, Int32 and Boolean for Real, Integer and
Boolean; a doStep that sets terminateSimulation is a Discard), so both kinds mix in one
system. They are instantiated, initialised, reset and terminated through fmpy's
objects, and stepped through them (``getReal``, ``setReal``, ``doStep``) unless the C
fast loop (:mod:`glider_cosim.master.fastloop`) makes the per-step calls: it calls the
same instances through the functions of the ``dll`` fmpy loaded and their
``component``, with the same bits (``GLIDER_COSIM_FASTLOOP=0`` turns it off).

Instances are connected output -> input by variable name
(:mod:`glider_cosim.master.plan`, where the coupling schemes are described). Time is
``t0 + k*h`` with an integer step counter.

Failures: an FMU call that returns fmi2Discard (fmi3Discard) stops the run cleanly
(:class:`FMUStopped`); fmi2Error/fmi2Fatal raise :class:`FMUCallError`. Either way the
rows recorded so far are kept (the recorder streams them); an instance that stopped or is
fine is terminated and freed, one in the error state is only freed (FMI allows nothing
else), and a fatal instance is never called again.
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import math
import weakref
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from .driven import DrivenInputs
from .errors import (
    FMUCallError,
    FMUStopped,
    Interrupted,
    MasterError,
    SystemSpecError,
    deferred_sigint,
    fmi_call_errors,
)
from .fastloop import FastLoop
from .fmi3 import fmi3_call_name
from .initial import InitialInputs
from .instance import Instance
from .plan import (
    check_wiring,
    driven_refs,
    initialization_order,
    plan_calls,
    plan_exchange,
    resolve,
)
from .spec import (
    COUPLINGS,
    DEFAULT_MAX_STEPS,
    Recorder,
    System,
    count_steps,
)

_LIVE: weakref.WeakSet[CoSimulation] = weakref.WeakSet()


@atexit.register
def _close_live() -> None:
    """Free the FMU instances of co-simulations nobody closed, while Python still runs
    (registered last, so it runs before the folders are removed)."""
    for sim in list(_LIVE):
        with contextlib.suppress(Exception):
            sim.close()


class CoSimulation(DrivenInputs, InitialInputs):
    """Load, connect, initialise and step a :class:`System`.

    Parameters
    ----------
    system : System
        The instances and their wiring.
    step : float
        Communication step, s (default 0.02 s, 50 Hz).
    coupling : str
        ``"gauss-seidel"`` or ``"jacobi"``.
    start_time : float
        Start time, s.
    max_steps : int
        Most communication steps :meth:`run` takes (a larger run is refused).
    """

    def __init__(
        self,
        system: System,
        step: float = 0.02,
        coupling: str = "gauss-seidel",
        start_time: float = 0.0,
        max_steps: int = DEFAULT_MAX_STEPS,
    ):
        if coupling not in COUPLINGS:
            raise SystemSpecError(
                f"coupling '{coupling}' is unknown: expected one of {', '.join(COUPLINGS)}"
            )
        if not (math.isfinite(step) and step > 0.0):
            raise SystemSpecError(f"step = {step!r} is invalid: expected a finite value > 0 s")
        self.system = system
        self.step_size = float(step)
        self._c_step = ctypes.c_double(self.step_size)
        self.coupling = coupling
        self.t0 = float(start_time)
        self.max_steps = int(max_steps)
        self.k = 0
        self.instances: dict[str, Instance] = {}
        self._keep_callbacks: list[Any] = []
        self._loaded = False
        self._initialized = False  # instances made and initialised (initialize)

    # ------------------------------------------------------------------ setup
    def _resolve(self, ref: str, causality: Iterable[str] | None = None):
        return resolve(self.instances, ref, causality)

    def load(self, before_checks: Callable[[CoSimulation], None] | None = None) -> None:
        """Read the FMUs and check the wiring; no FMU code runs yet.

        Parameters
        ----------
        before_checks : callable, optional
            Called with this co-simulation once the model descriptions are read (in
            :attr:`instances`) and before the system is checked against them; it may
            check or adapt :attr:`system`.
        """
        for name, path in self.system.fmus.items():
            self.instances[name] = Instance(name, Path(path))
        if before_checks is not None:
            before_checks(self)
        self._sources = check_wiring(self.system, self.instances)
        self._plan()
        self._loaded = True

    def _plan(self) -> None:
        """Order of the exchange and the batched value groups."""
        plan = plan_exchange(self.system, self.instances, self._sources, self.coupling)
        self._exchange_plan = plan
        self.columns, self._record, self._row_getter = plan.columns, plan.record, plan.row_getter
        self._driven, self.values = plan.driven, plan.values
        self._driven_base = {r: float(self.system.driven.get(r, 0.0)) for r in self._driven_refs()}
        #: the connected inputs set in Initialization Mode, in order, and those of them
        #: set before the inputs of a loop through them (dependencies declared by none)
        self._init_order, self.initialization_cut = initialization_order(
            self.instances, self._sources, driven_refs(self.system)
        )

    # ------------------------------------------------------------- FMI calls
    def _call(self, inst: Instance, call: str, fn: Callable[..., Any], *args: Any) -> Any:
        if not inst.alive:
            raise MasterError(f"{inst.name}: {call} on an instance that is not alive")
        try:
            return fn(*args)
        except fmi_call_errors() as err:
            self._raise(inst, call, int(err.status))

    def _set_value(self, inst: Instance, name: str, value: Any) -> None:
        v = inst.vars[name]
        s = inst.slave
        vr = [v.valueReference]
        if v.type == "Real":
            self._call(inst, f"fmi2SetReal({name})", s.setReal, vr, [float(value)])
        elif v.type == "Integer":
            self._call(inst, f"fmi2SetInteger({name})", s.setInteger, vr, [int(value)])
        elif v.type == "Boolean":
            self._call(inst, f"fmi2SetBoolean({name})", s.setBoolean, vr, [bool(value)])
        else:
            raise SystemSpecError(f"{inst.name}.{name}: type {v.type} cannot be set")

    def initialize(self) -> None:
        """Instantiate, set parameters, initialise every instance.

        Once: nothing is done when they are initialised and nothing has stepped since
        (``initialize()``, then :meth:`run`); after steps (a second :meth:`run`), the
        earlier instances are freed before new ones are made.
        """
        live = [inst.alive for inst in self.instances.values()]
        if self._initialized and self.k == 0 and live and all(live):
            return
        if not self._loaded:
            self.load()
        for inst in self.instances.values():
            inst.free()  # an earlier run's, if alive
        _LIVE.add(self)
        for inst in self.instances.values():
            cb = inst.callbacks()
            self._keep_callbacks.append(cb)
            inst.instantiate(cb, self.t0)
        self._setup_instances()
        self._plan_calls()
        self._initialized = True

    def _setup_instances(self) -> None:
        """Set up, parameterise and initialise the (fresh or reset) instances: every one
        enters Initialization Mode, its inputs are set there and every one exits
        (:class:`~glider_cosim.master.initial.InitialInputs`)."""
        self.k = 0
        for inst in self.instances.values():
            s = inst.slave
            self._call(inst, "fmi2SetupExperiment", s.setupExperiment, None, self.t0)
            for name, value in self.system.parameters.get(inst.name, {}).items():
                self._set_value(inst, name, value)
            self._call(inst, "fmi2EnterInitializationMode", s.enterInitializationMode)
        self._reset_inputs()
        self._initialization_mode()

    def reset(
        self, parameters: dict[str, dict[str, Any]] | None = None, replace: bool = False
    ) -> None:
        """fmi2Reset every instance and initialise it again, for another run.

        pythonfmu's reset restores the defaults, so the system's parameters (updated
        with ``parameters``, per instance, or replaced by them with ``replace``: then
        every parameter not given returns to the FMU's default) are set again. Value
        references, call plans and loaded libraries are kept; each instance's log starts
        empty, so a failure of the next run is told by that run's messages. Raises
        :class:`MasterError` if an instance is in a fatal state (it cannot be reset:
        build a new :class:`CoSimulation`).
        """
        for inst in self.instances.values():
            if not inst.alive:
                raise MasterError(f"{inst.name}: cannot reset an instance that is not alive")
        for inst, params in (parameters or {}).items():
            if inst not in self.instances:
                raise SystemSpecError(f"reset: no instance '{inst}'")
            for name in params:
                self._resolve(f"{inst}.{name}", ("parameter", "input"))
        if replace:
            self.system.parameters = {k: dict(v) for k, v in (parameters or {}).items()}
        else:
            for inst, params in (parameters or {}).items():
                self.system.parameters.setdefault(inst, {}).update(params)
        for inst in self.instances.values():
            inst.log.clear()  # a run's failure is told by its own messages only
            self._call(inst, "fmi2Reset", inst.slave.reset)
            inst.failed = False
        self._setup_instances()

    # ---------------------------------------------------------------- stepping
    def _raise(self, inst: Instance, call: str, status: int) -> None:
        t = self.t0 + self.k * self.step_size
        if status >= 4:
            inst.fatal = True
            inst.alive = False
        elif status == 3:
            inst.failed = True
        cls = FMUStopped if status == 2 else FMUCallError
        if inst.fmi == 3:
            call = fmi3_call_name(call)
        raise cls(inst.name, call, t, status, inst.log, inst.fmi)

    def _plan_calls(self) -> None:
        """The per-step calls: through the instances' objects, or the C fast loop."""
        calls = plan_calls(self.instances, self._exchange_plan)
        self._slave_ops = calls.slave_ops
        self._exchange_ops, self._steppers = calls.exchange_ops, calls.steppers
        self._fast = calls.fast
        self._reads, self._row_from_reads = calls.reads, calls.row_from_reads
        self._read_arrays = [value for _, value in self._reads]
        self._block_ready: bool | None = None  # rows of whole blocks of steps from C
        self._driven_last: dict[int, list[float] | None] = dict.fromkeys(range(len(self._driven)))

    def _fast_exchange(self) -> None:
        """The planned exchange from C; raises for the call that failed."""
        i, status = self._fast.exchange()
        if i >= 0:
            op = self._exchange_ops[i]
            self._raise(op[1], op[3], status)

    def _exchange(self) -> None:
        vals = self.values
        if self._fast is not None:
            self._fast_exchange()
            for names, value in self._reads:
                vals.update(zip(names, value[:]))
            return
        call = self._call
        for read, inst, method, name, vrs, arg in self._slave_ops:
            if read:
                vals.update(zip(arg, call(inst, name, method, vrs)))
            else:
                call(inst, name, method, vrs, arg(vals))

    def communication_point(self) -> tuple[float, ...]:
        """Exchange values at ``t_k`` (events included) and return the recorded row."""
        t = self.t0 + self.k * self.step_size
        self._drive(t)
        if self._row_from_reads is not None and not self._pending_events:
            self._fast_exchange()
            flat: list[float] = []
            for value in self._read_arrays:
                flat += value[:]
            return (t, *self._row_from_reads(flat))
        self._exchange()
        if self._events(t):
            self._drive(t)
            self._exchange()
        return (t, *self._row_getter(self.values))

    def do_step(self) -> None:
        """Step every instance from ``t_k`` to ``t_k + h``."""
        t = self.t0 + self.k * self.step_size
        if self._fast is not None:
            i, status = self._fast.step(ctypes.c_double(t), self._c_step)
            if i >= 0:
                self._raise(self._steppers[i][0], "fmi2DoStep", status)
            self.k += 1
            return
        h = self.step_size
        for inst in self.instances.values():
            self._call(inst, "fmi2DoStep", inst.slave.doStep, t, h)
        self.k += 1

    def run(self, stop_time: float, recorder: Recorder) -> None:
        """Initialise, then step to ``stop_time`` recording every point (t0 included).

        Raises :class:`FMUStopped` or :class:`FMUCallError` after the rows computed so
        far were handed to ``recorder``; the caller closes it and frees the instances
        (:meth:`close`).
        """
        n = count_steps(stop_time - self.t0, self.step_size, self.max_steps)
        with deferred_sigint() as interrupted:
            self.initialize()
            recorder.start(self.columns)
            recorder.row(self.communication_point())
            self.advance(n, recorder, interrupted)

    def advance(
        self, n: int, recorder: Recorder, interrupted: Callable[[], int] = lambda: 0
    ) -> None:
        """``n`` macro steps from the current point, each row handed to ``recorder``
        (whole blocks of steps run in C where nothing is driven or pending); raises
        :class:`Interrupted` when ``interrupted()`` returns a signal number."""
        done = 0
        while done < n:
            if signum := interrupted():
                raise Interrupted(signum)
            if self._runs_in_blocks():
                done += self._run_block(min(FastLoop.RUN_BLOCK, n - done), recorder)
                continue
            self.do_step()
            recorder.row(self.communication_point())
            done += 1

    def _runs_in_blocks(self) -> bool:
        """True when whole blocks of steps can run in C: the fast loop, constant inputs
        already set, no event pending, every recorded column read by the exchange."""
        if self._fast is None or self._pending_events or self._row_from_reads is None:
            return False
        if not (self._drive_static and self._drive_done):
            return False
        if self._block_ready is None:
            self._block_ready = self._fast.record(self._record)
        return self._block_ready

    def _run_block(self, n: int, recorder: Recorder) -> int:
        """``n`` macro steps in C, their rows handed to ``recorder``; raises as
        :meth:`do_step` and :meth:`communication_point` would, after the rows before."""
        done, where, index, status = self._fast.run(self.t0, self.k, self.step_size, n)
        ncol = len(self._record) + 1
        rows = self._fast.rows
        block = getattr(recorder, "rows_block", None)
        if block is not None:
            block(rows, done, ncol)
        else:
            for j in range(done):
                recorder.row(tuple(rows[j * ncol : (j + 1) * ncol]))
        self.k += done
        if where == 0:
            self._raise(self._steppers[index][0], "fmi2DoStep", status)
        if where == 1:
            self.k += 1  # the step was made; the exchange after it failed
            op = self._exchange_ops[index]
            self._raise(op[1], op[3], status)
        return done

    def close(self) -> None:
        """Terminate and free every instance that is not in a fatal state."""
        for inst in self.instances.values():
            inst.free()
