"""Fixed-step co-simulation master on fmpy for FMI 2.0 and FMI 3.0 co-simulation FMUs.

FMI 2.0 instances run on ``fmpy.fmi2``; FMI 3.0 ones on ``fmpy.fmi3.FMU3Slave`` behind
the same FMI 2.0-named calls (:mod:`glider_cosim.master.fmi3`: Float64, Int32 and Boolean
for Real, Integer and Boolean; a doStep that sets terminateSimulation is a Discard), so
both kinds mix in one system and share the C fast loop.

Instances are connected output -> input by variable name; value references come from
each FMU's model description. Time is ``t0 + k*h`` with an integer step counter.

Coupling schemes (what happens at every communication point ``t_k``):

``gauss-seidel`` (default)
    Values are exchanged in the order of the declared dependencies: outputs without
    direct feedthrough are read first, then each instance with direct feedthrough gets
    its inputs and is read (in topological order), then the remaining inputs are set;
    all instances then step from ``t_k`` to ``t_k + h``. A feedthrough output (our
    controller) therefore acts on inputs set at the same point.
``jacobi``
    All outputs are read, then all inputs are set, then all instances step: a
    feedthrough output acts on the inputs of the previous point (one extra sample).

Failures: an FMU call that returns fmi2Discard (fmi3Discard) stops the run cleanly
(:class:`FMUStopped`); fmi2Error/fmi2Fatal raise :class:`FMUCallError`. Either way the
rows recorded so far are kept (the recorder streams them); an instance that stopped or is
fine is terminated and freed, one in the error state is only freed (FMI allows nothing
else), and a fatal instance is never called again.
"""

from __future__ import annotations

import atexit
import bisect
import contextlib
import ctypes
import math
import operator
import shutil
import signal
import threading
import weakref
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from fmpy import calloc as fmpy_calloc
from fmpy import free as fmpy_free
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

from glider_cosim.inputs.archives import InputFileError, read_fmu, safe_extract
from glider_cosim.inputs.tempdirs import new_temp_dir
from glider_cosim.inputs.text import one_line, quote
from glider_cosim.master.fastloop import FastLoop
from glider_cosim.master.fmi3 import (
    TYPE_AS_FMI2,
    FMU3Adapter,
    fmi3_call_name,
    fmi3LogMessageCallback,
)
from glider_fmi.compile import PYTHON_CONFIG_FILE

COUPLINGS = ("gauss-seidel", "jacobi")
#: default limit of communication steps in one run (``--max-steps``)
DEFAULT_MAX_STEPS = 1_000_000
#: the calls made at every step, through :meth:`Instance.call_dll`
_HOT_CALLS = tuple(f"fmi2{a}{t}" for a in ("Get", "Set") for t in ("Real", "Integer", "Boolean"))
_HOT_CALLS += ("fmi2DoStep",)
_C_TRUE = ctypes.c_int(1)
_STATUS = {0: "fmi2OK", 1: "fmi2Warning", 2: "fmi2Discard", 3: "fmi2Error", 4: "fmi2Fatal"}
_STATUS3 = {k: v.replace("fmi2", "fmi3") for k, v in _STATUS.items()}
_CTYPES = {"Real": ctypes.c_double, "Integer": ctypes.c_int, "Boolean": ctypes.c_int}


class MasterError(Exception):
    """Base of the master's errors."""


class SystemSpecError(MasterError, ValueError):
    """The system is ill-formed: unknown instance or variable, type mismatch, input left
    unconnected, algebraic loop, bad step or stop time."""


class FMUCallError(MasterError, RuntimeError):
    """An FMI call returned fmi2Error or fmi2Fatal (fmi3Error, fmi3Fatal).

    Attributes ``instance``, ``call``, ``time`` (s), ``status``, ``log`` (the FMU's own
    messages for that instance) and ``fmi`` (the FMI version, 2 or 3: the call and the
    status are named in its terms).
    """

    def __init__(
        self, instance: str, call: str, time: float, status: int, log: Sequence[str], fmi: int = 2
    ):
        self.instance, self.call, self.time, self.status = instance, call, time, status
        self.log = list(log)
        self.fmi = fmi
        names = _STATUS3 if fmi == 3 else _STATUS
        errors = [m for m in self.log if m.startswith((f"[{names[3]}]", f"[{names[2]}]"))]
        detail = (errors[0] if errors else self.log[-1]) if self.log else "no log message"
        detail = " ".join(detail.split())
        # the FMU's message often starts with the instance's and the call's names (ours
        # do), which are said already
        status_tag, _, text = detail.partition("] ")
        base = call.partition("(")[0]
        if text.startswith(f"{instance}: {base}: "):
            text = text.removeprefix(f"{instance}: ")
            detail = f"{status_tag}] {text}"
        if text.startswith(f"{base}: "):
            detail = f"{status_tag}] {text[len(base) + 2 :]}"
        super().__init__(
            f"{instance}: {call} at t = {time:.6g} s returned {names.get(status, status)}: {detail}"
        )


class FMUStopped(FMUCallError):
    """An FMI call returned fmi2Discard (fmi3Discard, or fmi3DoStep set
    terminateSimulation): the FMU stopped the run cleanly (e.g. a stall)."""


class Interrupted(KeyboardInterrupt):
    """The run was stopped by SIGINT (Ctrl-C) or SIGTERM at a communication point.

    ``signum`` is the signal's number.
    """

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signum)
        self.signum = int(signum)

    def describe(self) -> str:
        """``"interrupted by the user (Ctrl-C)"`` or ``"terminated (SIGTERM)"``."""
        if self.signum == signal.SIGTERM:
            return "terminated (SIGTERM)"
        return "interrupted by the user (Ctrl-C)"


@dataclass(frozen=True)
class VarRef:
    """``instance.variable``."""

    instance: str
    variable: str

    @classmethod
    def parse(cls, text: str) -> VarRef:
        inst, sep, var = text.partition(".")
        if not sep or not inst or not var:
            raise SystemSpecError(
                f"{quote(text)} is not a variable reference: expected instance.variable"
            )
        return cls(inst, var)

    def __str__(self) -> str:
        return f"{self.instance}.{self.variable}"


@dataclass
class Event:
    """Set variables once a condition first holds at a communication point.

    ``variable`` is ``"time"`` or ``instance.variable`` (an output); the condition is
    ``value >= threshold`` (``op=">="``) or ``value <= threshold``. Actions are applied
    ``delay`` seconds after the condition first holds.
    """

    variable: str
    op: str
    threshold: float
    actions: dict[str, float | int | bool]
    delay: float = 0.0
    fired_at: float | None = None
    applied: bool = False

    def holds(self, value: float) -> bool:
        return value >= self.threshold if self.op == ">=" else value <= self.threshold


@dataclass
class Disturbance:
    """A step (from ``time`` on) or pulse (``time`` to ``time + duration``) on an input."""

    target: str
    kind: str
    time: float
    value: float
    duration: float = 0.0

    def at(self, t: float) -> float:
        eps = 1e-9
        if t < self.time - eps:
            return 0.0
        if self.kind == "pulse" and t >= self.time + self.duration - eps:
            return 0.0
        return self.value


@dataclass
class System:
    """FMUs under instance names, parameters, connections and driven inputs."""

    fmus: dict[str, Path]
    connections: list[tuple[str, str]]
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: inputs the master drives (constant base value, plus disturbances)
    driven: dict[str, float] = field(default_factory=dict)
    disturbances: list[Disturbance] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)
    #: inputs driven by a table (times in s, values), held from each time to the next
    tables: dict[str, tuple[Sequence[float], Sequence[float]]] = field(default_factory=dict)
    #: variables recorded; None = every output of every instance
    record: list[str] | None = None


class Recorder(Protocol):
    """Receives the column names once, then one row per communication point."""

    def start(self, columns: Sequence[str]) -> None: ...

    def row(self, values: Sequence[float]) -> None: ...

    def close(self) -> None: ...


def _tuple_getter(keys: Sequence[Any]) -> Callable[[Any], tuple]:
    """``d -> tuple(d[k] for k in keys)``, as one C-level call."""
    get = operator.itemgetter(*keys)
    return get if len(keys) > 1 else (lambda d: (get(d),))


class _Group:
    """Preallocated value-reference and value arrays for a batched get/set."""

    def __init__(self, vrs: Sequence[int], type_: str):
        n = len(vrs)
        self.n = n
        self.cn = ctypes.c_size_t(n)  # passed as is: no conversion per call
        self.type = type_
        self.vr = (ctypes.c_uint * n)(*vrs)
        self.value = (_CTYPES[type_] * n)()


@contextlib.contextmanager
def _deferred_sigint():
    """Turn Ctrl-C and SIGTERM into a flag checked between steps (main thread only).

    A KeyboardInterrupt raised inside an FMU's Python code would become fmi2Fatal; the
    master stops at the next communication point instead and raises
    :class:`Interrupted` there. Yields a function returning the signal number or 0.
    """
    if threading.current_thread() is not threading.main_thread():
        yield lambda: 0
        return
    flag: list[int] = []

    def handler(signum, frame):
        flag.append(signum)

    old = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield lambda: flag[0] if flag else 0
    finally:
        for sig, h in old.items():
            signal.signal(sig, h)


_EXTRACTED: dict[tuple[str, int, int], str] = {}


def _extracted(fmu: Path) -> str:
    """Folder an FMU is unpacked to, once per process and FMU file version.

    Instances of the same FMU share the unpacked binary, and a binary is never unloaded
    (no dlclose): unloading and reloading C++ libraries with thread-local storage while
    other threads (e.g. OpenBLAS's) live can corrupt the heap at process exit. The
    folders are removed at exit.
    """
    st = fmu.stat()
    key = (str(fmu.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _EXTRACTED or not Path(_EXTRACTED[key]).is_dir():
        folder = new_temp_dir(f"{fmu.stem[:40]}_")
        try:
            safe_extract(fmu, folder, f"FMU {quote(fmu.name)}")
        except InputFileError:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        _EXTRACTED[key] = str(folder)
    return _EXTRACTED[key]


@atexit.register
def _remove_extracted() -> None:
    for folder in _EXTRACTED.values():
        shutil.rmtree(folder, ignore_errors=True)


_LIVE: weakref.WeakSet[CoSimulation] = weakref.WeakSet()


@atexit.register
def _close_live() -> None:
    """Free the FMU instances of co-simulations nobody closed, while Python still runs
    (registered last, so it runs before the folders are removed)."""
    for sim in list(_LIVE):
        with contextlib.suppress(Exception):
            sim.close()


def count_steps(span: float, step: float, max_steps: int = DEFAULT_MAX_STEPS) -> int:
    """Number of communication steps of ``step`` s in ``span`` s.

    Raises
    ------
    SystemSpecError
        ``span`` or ``step`` not finite and > 0, ``step`` larger than ``span``, ``span``
        not a whole number of steps (to 1e-6 of a step), or more than ``max_steps``.
    """
    if not (isinstance(span, int | float) and math.isfinite(span) and span > 0):
        raise SystemSpecError(
            f"stop time {quote(span)} s is invalid: expected a finite value > the start time"
        )
    if not (isinstance(step, int | float) and math.isfinite(step) and step > 0):
        raise SystemSpecError(f"step = {quote(step)} s is invalid: expected a finite value > 0")
    ratio = span / step
    if not math.isfinite(ratio) or ratio > max_steps + 0.5:
        raise SystemSpecError(
            f"step {step:.6g} s over {span:.6g} s is {ratio:.3g} steps: more than the limit "
            f"of {max_steps} (option --max-steps)"
        )
    if ratio < 1 - 1e-6:
        raise SystemSpecError(f"step {step:.6g} s is longer than the run ({span:.6g} s)")
    n = round(ratio)
    if abs(ratio - n) > 1e-6:
        raise SystemSpecError(
            f"the run ({span:.6g} s) is not a whole number of steps of {step:.6g} s "
            f"({ratio:.6g} steps)"
        )
    return n


class Instance:
    """One FMU instance under a name (fmpy ``FMU2Slave``, or ``FMU3Slave`` behind
    :class:`~glider_cosim.master.fmi3.FMU3Adapter`, with batched value access)."""

    def __init__(self, name: str, fmu: Path):
        self.name = name
        self.fmu = Path(fmu)
        try:  # complete and readable, checked before the binary is loaded
            self.md = read_fmu(self.fmu, f"instance {name}")
        except InputFileError as err:
            raise SystemSpecError(str(err)) from None
        #: FMI version, 2 or 3
        self.fmi = 3 if self.md.fmiVersion.startswith("3") else 2
        if self.fmi == 3:  # Float64, Int32 as Real, Integer (this description is ours)
            for v in self.md.modelVariables:
                v.type = TYPE_AS_FMI2.get(v.type, v.type)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.outputs = [v.name for v in self.md.modelVariables if v.causality == "output"]
        self.inputs = [v.name for v in self.md.modelVariables if v.causality == "input"]
        # outputs that depend directly on inputs (None = all inputs, conservatively)
        self.feedthrough = {
            u.variable.name
            for u in self.md.outputs
            if u.dependencies is None or any(d.causality == "input" for d in u.dependencies)
        }
        try:
            self.unzipdir = _extracted(self.fmu)
        except InputFileError as err:
            raise SystemSpecError(f"instance {name}: {err}") from None
        try:
            self.slave = (FMU3Adapter if self.fmi == 3 else FMU2Slave)(
                guid=self.md.guid,
                unzipDirectory=self.unzipdir,
                modelIdentifier=self.md.coSimulation.modelIdentifier,
                instanceName=name,
            )
        except Exception as err:  # fmpy and ctypes raise plain Exception/OSError here
            raise SystemSpecError(
                f"instance {name}: the binary of {quote(self.fmu.name)} cannot be loaded "
                f"({one_line(err)})"
            ) from None
        self.log: list[str] = []
        self._call_dll: ctypes.CDLL | None = None
        self.alive = False  # instantiated and not fatal
        self.fatal = False
        self.failed = False  # returned fmi2Error: only getters, reset and free are allowed

    def call_dll(self) -> Any:
        """The FMU's binary for the per-step calls (for FMI 3, the shims of
        :meth:`~glider_cosim.master.fmi3.FMU3Adapter.calls` under the FMI 2 names).

        An FMU on our FMI runtime runs its code under the GIL, which the runtime takes for
        every call: it is called with the GIL held (``ctypes.PyDLL``), saving a release
        and re-acquisition per call. Any other FMU is called through fmpy's handle, with
        the GIL released.
        """
        if self._call_dll is None:
            dll = self.slave.dll
            on_runtime = (Path(self.unzipdir) / "resources" / PYTHON_CONFIG_FILE).is_file()
            if self.fmi == 3:  # the FMI 2-signature shims over the fmi3 calls
                self._call_dll = self.slave.calls(holds_gil=on_runtime)
                return self._call_dll
            if on_runtime:
                # the master passes ctypes objects of the exact types: no argtypes to check
                gil_dll = ctypes.PyDLL(dll._name)
                for name in _HOT_CALLS:
                    getattr(gil_dll, name).restype = ctypes.c_int
                dll = gil_dll
            self._call_dll = dll
        return self._call_dll

    def var(self, name: str, causality: Iterable[str] | None = None):
        v = self.vars.get(name)
        if v is None:
            raise SystemSpecError(
                f"instance {self.name} ({self.md.modelName}) has no variable {quote(name)}"
            )
        if causality is not None and v.causality not in causality:
            raise SystemSpecError(
                f"{self.name}.{name} has causality {v.causality}: expected one of "
                f"{', '.join(causality)}"
            )
        return v


class CoSimulation:
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

    # ------------------------------------------------------------------ setup
    def _resolve(self, ref: str, causality: Iterable[str] | None = None):
        r = VarRef.parse(ref)
        inst = self.instances.get(r.instance)
        if inst is None:
            raise SystemSpecError(
                f"{quote(ref)}: no instance {quote(r.instance)} (instances: "
                f"{', '.join(self.instances)})"
            )
        return inst, inst.var(r.variable, causality)

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
        sources: dict[str, str] = {}
        for src, dst in self.system.connections:
            try:
                si, sv = self._resolve(src, ("output",))
                di, dv = self._resolve(dst, ("input",))
            except SystemSpecError as err:
                raise SystemSpecError(f"connection {src} -> {dst}: {err}") from None
            if sv.type != dv.type:
                raise SystemSpecError(
                    f"connection {src} -> {dst}: type mismatch ({sv.type} -> {dv.type})"
                )
            if dst in sources:
                raise SystemSpecError(f"input {dst} is connected twice ({sources[dst]}, {src})")
            sources[dst] = src
        for ref in self._driven_refs():
            try:
                _, v = self._resolve(ref, ("input",))
            except SystemSpecError as err:
                raise SystemSpecError(f"driven input {ref}: {err}") from None
            if v.type != "Real":
                raise SystemSpecError(f"driven input {ref} must be Real, is {v.type}")
            if ref in sources:
                raise SystemSpecError(f"input {ref} is both connected and driven")
        driven = set(self._driven_refs())
        for inst in self.instances.values():
            for name in inst.inputs:
                ref = f"{inst.name}.{name}"
                if ref not in sources and ref not in driven:
                    raise SystemSpecError(
                        f"input {ref} is left unconnected: connect it or drive it "
                        "(a constant, a table or a disturbance)"
                    )
        for inst_name, params in self.system.parameters.items():
            for name in params:
                self._resolve(f"{inst_name}.{name}", ("parameter", "input"))
        for i, ev in enumerate(self.system.events):
            try:
                if ev.variable != "time":
                    self._resolve(ev.variable, ("output",))
                for target in ev.actions:
                    self._resolve(target, ("parameter", "input"))
            except SystemSpecError as err:
                raise SystemSpecError(f"event[{i}]: {err}") from None
        for ref in self.system.record or ():
            try:
                self._resolve(ref)
            except SystemSpecError as err:
                raise SystemSpecError(f"record {quote(ref)}: {err}") from None
        self._sources = sources
        self._plan()
        self._loaded = True

    def _plan(self) -> None:
        """Order of the exchange and the batched value groups."""
        insts = self.instances
        ft = {n for n, i in insts.items() if i.feedthrough and self.coupling == "gauss-seidel"}
        # feedthrough instance A must be resolved before B if B reads a feedthrough output of A
        deps: dict[str, set[str]] = {n: set() for n in ft}
        for dst, src in self._sources.items():
            s, d = VarRef.parse(src), VarRef.parse(dst)
            if (
                s.instance in ft
                and s.variable in insts[s.instance].feedthrough
                and d.instance in ft
            ):
                deps[d.instance].add(s.instance)
        order: list[str] = []
        while deps:
            ready = sorted(n for n, ds in deps.items() if not ds - set(order))
            if not ready:
                raise SystemSpecError(
                    "algebraic loop through direct-feedthrough outputs of "
                    f"{', '.join(sorted(deps))}: not supported"
                )
            for n in ready:
                order.append(n)
                del deps[n]
        self._ft_order = order
        self._plain = [n for n in insts if n not in ft]
        # recorded columns: every output by default (non-Real ones as numbers)
        record = self.system.record
        if record is None:
            record = [f"{n}.{o}" for n, i in insts.items() for o in i.outputs]
        needed = list(
            dict.fromkeys(
                record
                + list(self._sources.values())
                + [e.variable for e in self.system.events if e.variable != "time"]
            )
        )
        self.columns = ["time"] + record
        # per instance: one read group per type (outputs it must provide)
        self._read: dict[str, list[tuple[_Group, list[str]]]] = {}
        for n, inst in insts.items():
            names = [VarRef.parse(r).variable for r in needed if VarRef.parse(r).instance == n]
            self._read[n] = self._groups(inst, names)
        # per instance: inputs to set from connections (per type)
        self._write: dict[str, list[tuple[_Group, list[str]]]] = {}
        for n, inst in insts.items():
            dsts = [d for d in self._sources if VarRef.parse(d).instance == n]
            self._write[n] = [
                (g, [self._sources[f"{n}.{v}"] for v in names])
                for g, names in self._groups(inst, [VarRef.parse(d).variable for d in dsts])
            ]
        # driven inputs: one batched group per instance
        self._driven: list[tuple[Instance, _Group, list[str]]] = []
        by_inst: dict[str, list[str]] = {}
        for ref in self._driven_refs():
            by_inst.setdefault(VarRef.parse(ref).instance, []).append(ref)
        for n, refs in by_inst.items():
            inst = insts[n]
            vrs = [inst.vars[VarRef.parse(r).variable].valueReference for r in refs]
            self._driven.append((inst, _Group(vrs, "Real"), refs))
        self._driven_base = {r: float(self.system.driven.get(r, 0.0)) for r in self._driven_refs()}
        self._record = list(record)
        getter = operator.itemgetter(*record) if record else (lambda v: ())
        self._row_getter = getter if len(record) != 1 else (lambda v: (getter(v),))
        self.values: dict[str, float] = dict.fromkeys(needed, 0.0)

    def _driven_refs(self) -> list[str]:
        sysm = self.system
        refs = list(sysm.driven) + [d.target for d in sysm.disturbances] + list(sysm.tables)
        return list(dict.fromkeys(refs))

    @staticmethod
    def _groups(inst: Instance, names: Sequence[str]) -> list[tuple[_Group, list[str]]]:
        by_type: dict[str, list[str]] = {}
        for n in names:
            by_type.setdefault(inst.vars[n].type, []).append(n)
        out = []
        for type_, ns in by_type.items():
            if type_ not in _CTYPES:
                raise SystemSpecError(f"{inst.name}.{ns[0]}: type {type_} is not supported")
            out.append((_Group([inst.vars[n].valueReference for n in ns], type_), ns))
        return out

    # ------------------------------------------------------------- FMI calls
    def _call(self, inst: Instance, call: str, fn: Callable[..., Any], *args: Any) -> Any:
        if not inst.alive:
            raise MasterError(f"{inst.name}: {call} on an instance that is not alive")
        try:
            return fn(*args)
        except FMICallException as err:
            self._raise(inst, call, int(err.status))

    def _make_callbacks(self, inst: Instance) -> Any:
        names = _STATUS3 if inst.fmi == 3 else _STATUS

        def logger(env, instance_name, status, category, message):
            text = message.decode("utf-8", "replace") if message else ""
            inst.log.append(f"[{names.get(status, status)}] {text}")
            del inst.log[:-50]

        if inst.fmi == 3:  # fmi3LogMessageCallback(env, status, category, message)
            cb3 = fmi3LogMessageCallback(lambda env, st, cat, msg: logger(env, None, st, cat, msg))
            self._keep_callbacks.append(cb3)
            return cb3

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy_calloc)  # void* restype
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy_free)
        self._keep_callbacks.append(cb)
        return cb

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
        """Instantiate, set parameters, initialise every instance."""
        if not self._loaded:
            self.load()
        _LIVE.add(self)
        for inst in self.instances.values():
            cb = self._make_callbacks(inst)
            try:
                if inst.fmi == 3:
                    inst.slave.instantiate(log_message=cb, loggingOn=True)
                else:
                    inst.slave.instantiate(callbacks=cb, loggingOn=True)
            except Exception as err:  # fmpy raises plain Exception here
                call = fmi3_call_name("fmi2Instantiate") if inst.fmi == 3 else "fmi2Instantiate"
                raise FMUCallError(inst.name, call, self.t0, 3, inst.log, inst.fmi) from err
            inst.alive = True
        self._setup_instances()
        self._plan_calls()

    def _setup_instances(self) -> None:
        """Set up, parameterise and initialise the (fresh or reset) instances."""
        self.k = 0
        for inst in self.instances.values():
            s = inst.slave
            self._call(inst, "fmi2SetupExperiment", s.setupExperiment, None, self.t0)
            for name, value in self.system.parameters.get(inst.name, {}).items():
                self._set_value(inst, name, value)
            self._call(inst, "fmi2EnterInitializationMode", s.enterInitializationMode)
            self._call(inst, "fmi2ExitInitializationMode", s.exitInitializationMode)
        for ev in self.system.events:
            ev.fired_at, ev.applied = None, False
        self._driven_base = {r: float(self.system.driven.get(r, 0.0)) for r in self._driven_refs()}
        self._pending_events = len(self.system.events)
        self._drive_static = not self.system.disturbances and not self.system.tables
        self._drive_done = False
        self._driven_last = dict.fromkeys(range(len(self._driven)))

    def reset(
        self, parameters: dict[str, dict[str, Any]] | None = None, replace: bool = False
    ) -> None:
        """fmi2Reset every instance and initialise it again, for another run.

        pythonfmu's reset restores the defaults, so the system's parameters (updated
        with ``parameters``, per instance, or replaced by them with ``replace``: then
        every parameter not given returns to the FMU's default) are set again. Value
        references, call plans and loaded libraries are kept. Raises
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
            self._call(inst, "fmi2Reset", inst.slave.reset)
            inst.failed = False
        self._setup_instances()

    # ---------------------------------------------------------------- stepping
    def _check(self, inst: Instance, call: str, status: int) -> None:
        """Raise for a status worse than fmi2Warning (raw ctypes calls)."""
        if status > 1:
            self._raise(inst, call, status)

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
        """Raw ctypes functions with preallocated arrays for the per-step calls."""
        self._readers: dict[str, list[tuple]] = {}
        self._writers: dict[str, list[tuple]] = {}
        for n, inst in self.instances.items():
            dll, comp = inst.call_dll(), ctypes.c_void_p(inst.slave.component)
            self._readers[n] = [
                (inst, getattr(dll, f"fmi2Get{g.type}"), f"fmi2Get{g.type}", comp, g.vr, g.cn,
                 g.value, [f"{n}.{v}" for v in names])
                for g, names in self._read[n]
            ]  # fmt: skip
            self._writers[n] = [
                (inst, getattr(dll, f"fmi2Set{g.type}"), f"fmi2Set{g.type}", comp, g.vr, g.cn,
                 g.value, srcs)
                for g, srcs in self._write[n]
            ]  # fmt: skip
        # the exchange of one communication point, flattened in its order
        ops = [(True, *r) for n in self._plain for r in self._readers[n]]
        for n in self._ft_order:
            ops += [(False, *w) for w in self._writers[n]]
            ops += [(True, *r) for r in self._readers[n]]
        ops += [(False, *w) for n in self._plain for w in self._writers[n]]
        # a write's values come from the value table in one call (a tuple for a slice)
        self._exchange_ops = [(*op, None if op[0] else _tuple_getter(op[-1])) for op in ops]
        self._steppers = [
            (inst, inst.call_dll().fmi2DoStep, ctypes.c_void_p(inst.slave.component))
            for inst in self.instances.values()
        ]
        # the same calls from C, one ctypes call per exchange and per step (if possible)
        hold_gil = all(
            getattr(i.call_dll(), "holds_gil", isinstance(i.call_dll(), ctypes.PyDLL))
            for i in self.instances.values()
        )
        self._fast = FastLoop.plan(self._exchange_ops, self._steppers, hold_gil)
        self._reads = [(op[8], op[7]) for op in self._exchange_ops if op[0]]
        # the recorded row straight from the read arrays (no value table) when possible
        flat = [name for names, _ in self._reads for name in names]
        pos = {name: i for i, name in enumerate(flat)}
        self._row_from_reads = None
        if self._fast is not None and self._record and all(r in pos for r in self._record):
            self._row_from_reads = _tuple_getter([pos[r] for r in self._record])
        self._read_arrays = [value for _, value in self._reads]
        self._block_ready: bool | None = None  # rows of whole blocks of steps from C
        self._driven_last: dict[int, list[float] | None] = dict.fromkeys(range(len(self._driven)))

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
            for i, value in enumerate(new):
                g.value[i] = value
            comp = ctypes.c_void_p(inst.slave.component)
            self._check(inst, "fmi2SetReal", inst.call_dll().fmi2SetReal(comp, g.vr, g.cn, g.value))
            self._driven_last[j] = new

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
        for read, inst, fn, call, comp, vr, n, value, names, sources in self._exchange_ops:
            if read:
                status = fn(comp, vr, n, value)
                if status > 1:
                    self._raise(inst, call, status)
                vals.update(zip(names, value[:]))  # the array as a list, in one call
            else:
                value[:] = sources(vals)
                status = fn(comp, vr, n, value)
                if status > 1:
                    self._raise(inst, call, status)

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
        t = ctypes.c_double(self.t0 + self.k * self.step_size)
        h = self._c_step
        if self._fast is not None:
            i, status = self._fast.step(t, h)
            if i >= 0:
                self._raise(self._steppers[i][0], "fmi2DoStep", status)
            self.k += 1
            return
        for inst, fn, comp in self._steppers:
            status = fn(comp, t, h, _C_TRUE)
            if status > 1:
                self._raise(inst, "fmi2DoStep", status)
        self.k += 1

    def run(self, stop_time: float, recorder: Recorder) -> None:
        """Initialise, then step to ``stop_time`` recording every point (t0 included).

        Raises :class:`FMUStopped` or :class:`FMUCallError` after the rows computed so
        far were handed to ``recorder``; the caller closes it and frees the instances
        (:meth:`close`).
        """
        n = count_steps(stop_time - self.t0, self.step_size, self.max_steps)
        with _deferred_sigint() as interrupted:
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
            if inst.alive:
                inst.alive = False
                slave = inst.slave
                if not inst.failed:
                    with contextlib.suppress(FMICallException):
                        slave.terminate()
                # free the instance but keep the library loaded (see _extracted)
                with contextlib.suppress(FMICallException):
                    slave.fmi2FreeInstance(slave.component)
