"""Turning a System into the call plan: wiring checks, exchange order, batched calls.

Instances are connected output -> input by variable name; value references come from
each FMU's model description.

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
"""

from __future__ import annotations

import ctypes
import operator
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from ..inputs.text import did_you_mean, quote
from .errors import SystemSpecError
from .fastloop import FastLoop, fast_loop_wanted
from .instance import Instance
from .spec import System, VarRef

_CTYPES = {"Real": ctypes.c_double, "Integer": ctypes.c_int, "Boolean": ctypes.c_int}


def _tuple_getter(keys: Sequence[Any]) -> Callable[[Any], tuple]:
    """``d -> tuple(d[k] for k in keys)``, as one C-level call."""
    get = operator.itemgetter(*keys)
    return get if len(keys) > 1 else (lambda d: (get(d),))


class Group:
    """Preallocated value-reference and value arrays for a batched get/set."""

    def __init__(self, vrs: Sequence[int], type_: str):
        n = len(vrs)
        self.n = n
        self.cn = ctypes.c_size_t(n)  # passed as is: no conversion per call
        self.type = type_
        self.vr = (ctypes.c_uint * n)(*vrs)
        self.value = (_CTYPES[type_] * n)()


def resolve(instances: dict[str, Instance], ref: str, causality: Iterable[str] | None = None):
    """The instance and the model variable of ``instance.variable`` (of a causality in
    ``causality``, if given); raises :class:`SystemSpecError`."""
    r = VarRef.parse(ref)
    inst = instances.get(r.instance)
    if inst is None:
        raise SystemSpecError(
            f"{quote(ref)}: no instance {quote(r.instance)} (instances: {', '.join(instances)})"
            + did_you_mean(r.instance, instances)
        )
    return inst, inst.var(r.variable, causality)


def driven_refs(system: System) -> list[str]:
    """The inputs the master drives: constant, disturbed or from a table, once each."""
    refs = list(system.driven) + [d.target for d in system.disturbances] + list(system.tables)
    return list(dict.fromkeys(refs))


def check_wiring(system: System, instances: dict[str, Instance]) -> dict[str, str]:
    """Check ``system`` against the model descriptions of its ``instances``; returns the
    source of every connected input (``{input: output}``).

    Raises :class:`SystemSpecError` for an unknown instance or variable, a connection of
    two types, an input connected twice, connected and driven or left unconnected, and
    parameters, events and recorded variables that name no fitting variable.
    """
    sources: dict[str, str] = {}
    for src, dst in system.connections:
        try:
            si, sv = resolve(instances, src, ("output",))
            di, dv = resolve(instances, dst, ("input",))
        except SystemSpecError as err:
            raise SystemSpecError(f"connection {src} -> {dst}: {err}") from None
        if sv.type != dv.type:
            raise SystemSpecError(
                f"connection {src} -> {dst}: type mismatch ({sv.type} -> {dv.type})"
            )
        if dst in sources:
            raise SystemSpecError(f"input {dst} is connected twice ({sources[dst]}, {src})")
        sources[dst] = src
    for ref in driven_refs(system):
        try:
            _, v = resolve(instances, ref, ("input",))
        except SystemSpecError as err:
            raise SystemSpecError(f"driven input {ref}: {err}") from None
        if v.type != "Real":
            raise SystemSpecError(f"driven input {ref} must be Real, is {v.type}")
        if ref in sources:
            raise SystemSpecError(f"input {ref} is both connected and driven")
    driven = set(driven_refs(system))
    for inst in instances.values():
        for name in inst.inputs:
            ref = f"{inst.name}.{name}"
            if ref not in sources and ref not in driven:
                raise SystemSpecError(
                    f"input {ref} is left unconnected: connect it or drive it "
                    "(a constant, a table or a disturbance)"
                )
    for inst_name, params in system.parameters.items():
        for name in params:
            resolve(instances, f"{inst_name}.{name}", ("parameter", "input"))
    for i, ev in enumerate(system.events):
        try:
            if ev.variable != "time":
                resolve(instances, ev.variable, ("output",))
            for target in ev.actions:
                resolve(instances, target, ("parameter", "input"))
        except SystemSpecError as err:
            raise SystemSpecError(f"event[{i}]: {err}") from None
    for ref in system.record or ():
        try:
            resolve(instances, ref)
        except SystemSpecError as err:
            raise SystemSpecError(f"record {quote(ref)}: {err}") from None
    return sources


def exchange_order(
    instances: dict[str, Instance], sources: dict[str, str], coupling: str
) -> tuple[list[str], list[str]]:
    """The instances with direct feedthrough in the order they are resolved (none for
    ``jacobi``), and the others; raises :class:`SystemSpecError` for an algebraic loop."""
    ft = {n for n, i in instances.items() if i.feedthrough and coupling == "gauss-seidel"}
    # feedthrough instance A must be resolved before B if B reads a feedthrough output of A
    deps: dict[str, set[str]] = {n: set() for n in ft}
    for dst, src in sources.items():
        s, d = VarRef.parse(src), VarRef.parse(dst)
        if (
            s.instance in ft
            and s.variable in instances[s.instance].feedthrough
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
    return order, [n for n in instances if n not in ft]


def initialization_order(
    instances: dict[str, Instance], sources: dict[str, str], preset: Iterable[str]
) -> tuple[list[tuple[str, str]], list[str]]:
    """The connected inputs in the order they are set in Initialization Mode, as
    ``(input, its source)``, and the inputs set without the values of a loop.

    An input is set from its source once every input the source's value depends on
    there (its instance's ``<InitialUnknowns>`` dependencies) is set: the ``preset`` ones
    (driven) first, then in that order, the declared order deciding between those that
    are ready. A loop of such dependencies is cut at its first input in the declared
    order (its source is read with the loop's inputs not set yet).
    """
    done = set(preset)
    pending = list(sources.items())
    order: list[tuple[str, str]] = []
    cut: list[str] = []

    def ready(src: str) -> bool:
        s = VarRef.parse(src)
        inst = instances[s.instance]
        needs = inst.initial_inputs.get(s.variable, set())
        return all(f"{s.instance}.{n}" in done for n in (inst.inputs if needs is None else needs))

    while pending:
        i = next((i for i, (_, src) in enumerate(pending) if ready(src)), None)
        dst, src = pending.pop(0 if i is None else i)
        done.add(dst)
        order.append((dst, src))
        if i is None:
            cut.append(dst)
    return order, cut


def value_groups(inst: Instance, names: Sequence[str]) -> list[tuple[Group, list[str]]]:
    """One :class:`Group` per type of the variables ``names`` of ``inst``, with their names."""
    by_type: dict[str, list[str]] = {}
    for n in names:
        by_type.setdefault(inst.vars[n].type, []).append(n)
    out = []
    for type_, ns in by_type.items():
        if type_ not in _CTYPES:
            raise SystemSpecError(f"{inst.name}.{ns[0]}: type {type_} is not supported")
        out.append((Group([inst.vars[n].valueReference for n in ns], type_), ns))
    return out


@dataclass
class Exchange:
    """What is read, set and recorded at a communication point, and in which order."""

    #: feedthrough instances in the order they are resolved, and the other instances
    ft_order: list[str]
    plain: list[str]
    #: ``time`` and the recorded variables
    columns: list[str]
    record: list[str]
    #: per instance: its read groups (outputs it must provide) with the variables' names
    read: dict[str, list[tuple[Group, list[str]]]]
    #: per instance: its groups of connected inputs with their sources
    write: dict[str, list[tuple[Group, list[str]]]]
    #: driven inputs: one batched Real group per instance, with the inputs
    driven: list[tuple[Instance, Group, list[str]]]
    #: every variable read (recorded, a connection's source, an event's), 0.0 to start
    values: dict[str, float]
    #: the recorded row (without the time) from :attr:`values`
    row_getter: Callable[[dict[str, float]], tuple]


def plan_exchange(
    system: System, instances: dict[str, Instance], sources: dict[str, str], coupling: str
) -> Exchange:
    """Order of the exchange and the batched value groups."""
    ft_order, plain = exchange_order(instances, sources, coupling)
    # recorded columns: every output by default (non-Real ones as numbers)
    record = system.record
    if record is None:
        record = [f"{n}.{o}" for n, i in instances.items() for o in i.outputs]
    needed = list(
        dict.fromkeys(
            record
            + list(sources.values())
            + [e.variable for e in system.events if e.variable != "time"]
        )
    )
    read: dict[str, list[tuple[Group, list[str]]]] = {}
    for n, inst in instances.items():
        names = [VarRef.parse(r).variable for r in needed if VarRef.parse(r).instance == n]
        read[n] = value_groups(inst, names)
    write: dict[str, list[tuple[Group, list[str]]]] = {}
    for n, inst in instances.items():
        dsts = [d for d in sources if VarRef.parse(d).instance == n]
        write[n] = [
            (g, [sources[f"{n}.{v}"] for v in names])
            for g, names in value_groups(inst, [VarRef.parse(d).variable for d in dsts])
        ]
    driven: list[tuple[Instance, Group, list[str]]] = []
    by_inst: dict[str, list[str]] = {}
    for ref in driven_refs(system):
        by_inst.setdefault(VarRef.parse(ref).instance, []).append(ref)
    for n, refs in by_inst.items():
        inst = instances[n]
        vrs = [inst.vars[VarRef.parse(r).variable].valueReference for r in refs]
        driven.append((inst, Group(vrs, "Real"), refs))
    getter = operator.itemgetter(*record) if record else (lambda v: ())
    row_getter = getter if len(record) != 1 else (lambda v: (getter(v),))
    values = dict.fromkeys(needed, 0.0)
    return Exchange(
        ft_order, plain, ["time"] + record, list(record), read, write, driven, values, row_getter
    )


@dataclass
class Calls:
    """The per-step calls: through the instances' fmpy objects, or from the C fast loop."""

    #: the exchange of one communication point through the instances' objects (fmpy's
    #: ``FMU2Slave``, :class:`~glider_cosim.master.fmi3.FMU3Adapter`, ...), in its order:
    #: ``(read, inst, method, call, vrs, arg)``, ``arg`` the names of the values read, or
    #: for a write a function of the value table giving the values set
    slave_ops: list[tuple]
    #: the same exchange as raw ctypes functions with preallocated arrays for the fast
    #: loop: ``(read, inst, fn, call, comp, vr, n, value, names, sources)`` (empty
    #: without the fast loop)
    exchange_ops: list[tuple]
    #: ``(inst, fmi2DoStep, comp)`` per instance for the fast loop (empty without it)
    steppers: list[tuple]
    #: the fast loop: one ctypes call per exchange and per step, or None
    fast: FastLoop | None
    #: the read arrays with the names of their values, in the order of the exchange
    reads: list[tuple[list[str], Any]]
    #: the recorded row straight from the read arrays (no value table) when possible
    row_from_reads: Callable[[Any], tuple] | None


def _ordered(exchange: Exchange) -> list[tuple[bool, str, Group, list[str]]]:
    """The exchange's batched calls in order: ``(read, instance, group, names)``, names
    the variables read, or for a write the ``instance.variable`` each value comes from."""
    read = exchange.read
    ops = [(True, n, g, names) for n in exchange.plain for g, names in read[n]]
    for n in exchange.ft_order:
        ops += [(False, n, g, srcs) for g, srcs in exchange.write[n]]
        ops += [(True, n, g, names) for g, names in read[n]]
    ops += [(False, n, g, srcs) for n in exchange.plain for g, srcs in exchange.write[n]]
    return ops


def _as_ints(get: Callable[[list[int]], list]) -> Callable[[list[int]], list[int]]:
    """``get`` with its values as ints (FMI 3's Booleans come as bool)."""
    return lambda vr: [int(x) for x in get(vr)]


def plan_calls(instances: dict[str, Instance], exchange: Exchange) -> Calls:
    """The per-step calls: through the instances' objects, and for the C fast loop
    (:class:`~glider_cosim.master.fastloop.FastLoop`, if it can run) raw ctypes functions
    with preallocated arrays."""
    ordered = _ordered(exchange)
    slave_ops = []
    for read, n, g, names in ordered:
        inst = instances[n]
        if read:
            get = getattr(inst.slave, f"get{g.type}")
            get = get if g.type == "Real" else _as_ints(get)
            slave_ops.append((True, inst, get, f"fmi2Get{g.type}", list(g.vr),
                              [f"{n}.{v}" for v in names]))  # fmt: skip
        else:
            slave_ops.append((False, inst, getattr(inst.slave, f"set{g.type}"),
                              f"fmi2Set{g.type}", list(g.vr), _tuple_getter(names)))  # fmt: skip
    none = Calls(slave_ops, [], [], None, [], None)
    if not fast_loop_wanted():
        return none
    dlls = {n: inst.call_dll() for n, inst in instances.items()}
    if any(dll is None for dll in dlls.values()):
        return none  # an FMU the C loop cannot call (no compiler for FMI 3's shims, wasm)
    comps = {n: ctypes.c_void_p(inst.slave.component) for n, inst in instances.items()}
    ops = []
    for read, n, g, names in ordered:
        kind = "Get" if read else "Set"
        ops.append((read, instances[n], getattr(dlls[n], f"fmi2{kind}{g.type}"),
                    f"fmi2{kind}{g.type}", comps[n], g.vr, g.cn, g.value,
                    [f"{n}.{v}" for v in names] if read else names, None))  # fmt: skip
    steppers = [(inst, dlls[n].fmi2DoStep, comps[n]) for n, inst in instances.items()]
    hold_gil = all(getattr(dlls[n], "holds_gil", i.on_runtime) for n, i in instances.items())
    fast = FastLoop.plan(ops, steppers, hold_gil)
    if fast is None:
        return none
    reads = [(op[8], op[7]) for op in ops if op[0]]
    flat = [name for names, _ in reads for name in names]
    pos = {name: i for i, name in enumerate(flat)}
    row_from_reads = None
    record = exchange.record
    if record and all(r in pos for r in record):
        row_from_reads = _tuple_getter([pos[r] for r in record])
    return Calls(slave_ops, ops, steppers, fast, reads, row_from_reads)
