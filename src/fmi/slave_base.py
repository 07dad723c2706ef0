"""Shared FMI plumbing for the glider slaves (bundled in every FMU, same code).

A slave declares its variables as a table of :class:`Var`; this base registers them,
writes a complete modelDescription (units with a ``deg`` display unit for angles,
valid variabilities, ModelStructure with output dependencies and InitialUnknowns),
validates parameters and inputs, and saves, restores and serializes the internal state
with the FMU state.

The slaves run inside our FMI layer (``fmi2_layer.c`` with ``backend_python.c``), which
owns the FMI state machine: a Python exception raised here becomes ``fmi2Error`` with
its message passed to the host's logger; a clean stop (stall) is ``do_step`` returning
False, i.e. ``fmi2Discard``.
"""

from __future__ import annotations

import copy
import importlib.metadata
import math
import operator
from collections.abc import Sequence
from typing import Any
from xml.etree.ElementTree import Element, SubElement

from pythonfmu.enums import Fmi2Causality, Fmi2Status, Fmi2Variability
from pythonfmu.fmi2slave import Fmi2Slave
from pythonfmu.variables import Boolean, Integer, Real

from . import derivatives, state_codec
from .variables import ValidRange, Var  # noqa: F401 (re-exported: the slaves' tables)

DEG = 180.0 / math.pi


class RefusedValueError(ValueError):
    """A parameter or input value the slave refuses (the message names variable, value and
    the valid range); the runtime reports it as fmi2Error with the message alone."""

    fmi_message_only = True


# SI base-unit exponents of every unit the slaves use, and display units.
_UNITS: dict[str, dict[str, str]] = {
    "m": {"m": "1"},
    "m/s": {"m": "1", "s": "-1"},
    "m/s2": {"m": "1", "s": "-2"},
    "rad": {"rad": "1"},
    "rad/s": {"rad": "1", "s": "-1"},
    "rad/s2": {"rad": "1", "s": "-2"},
    "rad2": {"rad": "2"},
    "s": {"s": "1"},
    "Hz": {"s": "-1"},
    "N": {"kg": "1", "m": "1", "s": "-2"},
    "N.m": {"kg": "1", "m": "2", "s": "-2"},
    "kg": {"kg": "1"},
    "kg/m": {"kg": "1", "m": "-1"},
    "kg/s": {"kg": "1", "s": "-1"},
    "kg.m2": {"kg": "1", "m": "2"},
    "rad.s": {"rad": "1", "s": "1"},
}
_DISPLAY = {u: ("deg" + u[3:], DEG) for u in ("rad", "rad/s", "rad/s2", "rad.s")}


def _expected(v: Var) -> str:
    """A variable's valid range in words (an Integer's bounds as integers)."""
    return v.valid.describe(v.type == "Integer")


def _dependencies(knowns: Sequence[str], index: dict[str, int]) -> dict[str, str]:
    """FMI 2's ``dependencies`` (the knowns' indices, ascending) and ``dependenciesKind``
    (each ``dependent``) of an unknown; both empty when it depends on none."""
    deps = sorted(index[k] for k in knowns)
    kinds = " ".join("dependent" for _ in deps)
    return {"dependencies": " ".join(map(str, deps)), "dependenciesKind": kinds}


def _tuple_attrgetter(names: Sequence[str]) -> Any:
    """``obj -> tuple(getattr(obj, n) for n in names)``, as one C-level call."""
    if not names:
        return lambda obj: ()
    get = operator.attrgetter(*names)
    return get if len(names) > 1 else (lambda obj: (get(obj),))


class GliderSlave(derivatives.StateDerivatives, Fmi2Slave):
    """Base of the glider slaves: declare :attr:`VARIABLES`, implement :meth:`initialize`
    and :meth:`step`; list :attr:`FEEDTHROUGH` (output -> inputs it depends on directly).
    """

    VARIABLES: tuple[Var, ...] = ()
    FEEDTHROUGH: dict[str, tuple[str, ...]] = {}
    #: output -> the inputs and parameters its value in Initialization Mode depends on
    #: (FMI's <InitialUnknowns> dependencies; those the slave does not declare are left
    #: out); None, or an output not named: not declared (then every known)
    INITIAL_DEPENDENCIES: dict[str, tuple[str, ...]] | None = None
    #: outputs read through a getter that computes them (direct feedthrough)
    COMPUTED: tuple[str, ...] = ()
    #: attributes (besides the variables) saved with the FMU state
    INTERNAL_STATE: tuple[str, ...] = ()
    #: module prefixes whose objects may appear in a serialized FMU state
    STATE_MODULES: tuple[str, ...] = ("glider_",)

    log_categories = {
        **Fmi2Slave.log_categories,
        "logFmiCalls": "Every FMI call (only when named in fmi2SetDebugLogging).",
    }

    author = "glider-cosim"
    license = "MIT"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._initialized = False
        self._in_init = False  # in Initialization Mode (FMI's <InitialUnknowns> computed)
        self._time = 0.0
        self._discarded = False
        for v in self.VARIABLES:
            start = v.start
            if v.type == "Integer":
                start = int(start)
            elif v.type == "Boolean":
                start = bool(start)
            setattr(self, v.name, start)
            causality = getattr(Fmi2Causality, v.causality)
            desc = f"{v.description} [{v.unit}]"
            if v.causality == "parameter":
                variability = Fmi2Variability.tunable if v.tunable else Fmi2Variability.fixed
            elif v.type == "Real":
                variability = Fmi2Variability.continuous
            else:
                variability = Fmi2Variability.discrete
            cls = {"Real": Real, "Integer": Integer, "Boolean": Boolean}[v.type]
            self.register_variable(
                cls(v.name, causality=causality, variability=variability, description=desc)
            )
        self._inputs = tuple(v.name for v in self.VARIABLES if v.causality == "input")
        self._index_reals()

    def _index_reals(self) -> None:
        """Value reference -> getter / attribute name of every Real variable."""
        self._real_getters = {vr: v.getter for vr, v in self.vars.items() if isinstance(v, Real)}
        self._real_names = {vr: v.name for vr, v in self.vars.items() if isinstance(v, Real)}
        spec = {v.name: v for v in self.VARIABLES}
        self._spec_by_vr = {vr: spec[v.name] for vr, v in self.vars.items() if v.name in spec}
        self._real_inputs = {
            vr: n for vr, n in self._real_names.items() if self._spec_by_vr[vr].causality == "input"
        }
        self._plain_reals = {vr for vr, n in self._real_names.items() if n not in self.COMPUTED}
        spec_vrs = self._spec_by_vr.items()
        self._outputs_vr = frozenset(vr for vr, v in spec_vrs if v.causality == "output")
        self._get_cache: dict[tuple[int, ...], Any] = {}
        self._last_get: tuple[Any, Any] = (None, None)  # (references tuple, its getter)
        self._last_set: tuple[Any, tuple[str, ...]] = (None, ())  # (references, input names)
        self._input_values = _tuple_attrgetter(self._inputs)

    # ------------------------------------------------------------------ XML
    def to_xml(self, model_options: dict[str, str] | None = None) -> Element:  # noqa: D401
        root = super().to_xml(model_options or {})
        try:  # the model's version: the package that built it
            root.set("version", importlib.metadata.version("glider-cosim"))
        except importlib.metadata.PackageNotFoundError:
            pass
        spec = {v.name: v for v in self.VARIABLES}
        # units on the Real elements
        used = set()
        index = {}
        for i, sv in enumerate(root.find("ModelVariables"), start=1):
            name = sv.get("name")
            index[name] = i
            v = spec.get(name)
            real = sv.find("Real")
            if v is None or real is None:
                continue
            if real.get("start") is not None:  # pythonfmu writes %.16g: maybe another double
                real.set("start", repr(float(v.start)))
            if v.unit in _UNITS:
                real.set("unit", v.unit)
                used.add(v.unit)
                if v.unit in _DISPLAY:
                    real.set("displayUnit", _DISPLAY[v.unit][0])
        # UnitDefinitions go right after CoSimulation
        units = Element("UnitDefinitions")
        for u in sorted(used):
            ue = SubElement(units, "Unit", name=u)
            SubElement(ue, "BaseUnit", _UNITS[u])
            if u in _DISPLAY:
                dname, factor = _DISPLAY[u]
                SubElement(ue, "DisplayUnit", name=dname, factor=repr(factor))
        pos = list(root).index(root.find("CoSimulation")) + 1
        root.insert(pos, units)
        # ModelStructure: outputs with their direct dependencies (inputs), InitialUnknowns
        # with theirs in Initialization Mode (inputs and parameters)
        structure = root.find("ModelStructure")
        for child in list(structure):
            structure.remove(child)
        outputs = [v.name for v in self.VARIABLES if v.causality == "output"]
        if outputs:
            out_el = SubElement(structure, "Outputs")
            init_el = SubElement(structure, "InitialUnknowns")
            initial = self.INITIAL_DEPENDENCIES
            for name in outputs:
                attrs = {"index": str(index[name])}
                feedthrough = _dependencies(self.FEEDTHROUGH.get(name, ()), index)
                SubElement(out_el, "Unknown", attrs | feedthrough)
                if initial is not None and name in initial:  # a subclass may drop knowns
                    attrs |= _dependencies([k for k in initial[name] if k in index], index)
                SubElement(init_el, "Unknown", attrs)
        return derivatives.declare(self, root, index, _dependencies)  # states, Jacobian

    # ----------------------------------------------------------- validation
    def fail(self, message: str) -> None:
        """Refuse a value: raise :class:`RefusedValueError`, which the runtime reports as
        fmi2Error with ``message`` passed to the host's logger."""
        raise RefusedValueError(message)

    def validate_parameters(self) -> None:
        """Check every variable that declares a valid range (names value and range)."""
        for v in self.VARIABLES:
            if v.valid is None or v.causality == "output":
                continue
            value = getattr(self, v.name)
            if not v.valid.contains(float(value)):
                self.fail(f"{v.name} = {value!r} is invalid: expected {_expected(v)}")

    def check_inputs(self) -> None:
        """Refuse non-finite inputs at a step."""
        if all(map(math.isfinite, self._input_values(self))):
            return
        for name in self._inputs:
            value = getattr(self, name)
            if not math.isfinite(value):
                self.fail(
                    f"input {name} = {value!r} at t = {self._time:g} s is invalid: "
                    "expected a finite value"
                )

    # fast paths for the hot get/set calls (pythonfmu's generic ones check every type)
    def get_real(self, vrs: Sequence[int]) -> Sequence[float]:
        last_key, last = self._last_get
        if vrs is last_key:  # the runtime passes the same tuple while the references repeat
            return last(self)
        key = tuple(vrs)
        if self._in_init and not self._outputs_vr.isdisjoint(key):
            self._initial_values()  # outputs in Initialization Mode: as after Exit
        fast = self._get_cache.get(key)
        if fast is None:
            getters = self._real_getters
            if not key or not all(vr in getters for vr in key):
                return super().get_real(vrs)
            if all(vr in self._plain_reals for vr in key):
                attr = operator.attrgetter(*(self._real_names[vr] for vr in key))
                fast = attr if len(key) > 1 else (lambda obj: (attr(obj),))
            elif len(key) == 1:
                g0 = getters[key[0]]
                fast = lambda obj: [g0()]  # noqa: E731
            else:
                gs = tuple(getters[vr] for vr in key)
                fast = lambda obj: [g() for g in gs]  # noqa: E731
            self._get_cache[key] = fast
        if type(vrs) is tuple and not self._in_init:  # immutable: its identity stands
            self._last_get = (vrs, fast)  # for its contents (not in Initialization Mode)
        return fast(self)  # a sequence (the runtime takes any)

    def set_real(self, vrs: Sequence[int], values: Sequence[float]) -> None:
        last_key, names = self._last_set
        if vrs is last_key and len(values) == len(names):  # the same inputs as last time
            for name, value in zip(names, values):
                setattr(self, name, value)
            return
        inputs = self._real_inputs
        if type(vrs) is tuple and all(vr in inputs for vr in vrs):
            self._last_set = (vrs, tuple(inputs[vr] for vr in vrs))
        for vr, value in zip(vrs, values, strict=True):
            name = inputs.get(vr)
            if name is not None:
                setattr(self, name, value)
            else:
                self._set_other(vr, value, super().set_real)

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        for vr, value in zip(vrs, values, strict=True):
            self._set_other(vr, value, super().set_integer)

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        for vr, value in zip(vrs, values, strict=True):
            self._set_other(vr, value, super().set_boolean)

    def _set_other(self, vr: int, value: Any, setter: Any) -> None:
        """Set a parameter (checked once initialised) or refuse to set an output."""
        v = self._spec_by_vr.get(vr)
        if v is None:
            self.fail(f"value reference {vr} is unknown")
        if v.causality in derivatives.UNSETTABLE:
            self.fail(f"{v.name} is {derivatives.UNSETTABLE[v.causality]}: it cannot be set")
        if self._initialized and v.causality == "parameter":
            if not v.tunable:
                self.fail(
                    f"{v.name} is a fixed parameter: it cannot be set after initialisation "
                    "(only tunable parameters can)"
                )
            if v.valid is not None and not v.valid.contains(float(value)):
                self.fail(f"{v.name} = {value!r} is invalid: expected {_expected(v)}")
        setter([vr], [value])

    # ------------------------------------------------------------ lifecycle
    def setup_experiment(self, start_time: float, stop_time: float | None, tolerance: float | None):
        self._time = float(start_time)

    def enter_initialization_mode(self) -> None:
        self._in_init = True
        self._last_get = (None, None)  # every get in the mode takes _initial_values

    def exit_initialization_mode(self) -> None:
        self._in_init = False
        self._initial_values()
        self._initialized = True

    def _initial_values(self) -> None:
        """The initial state and outputs from the parameters, start values and inputs
        set so far: at Exit, and in Initialization Mode before an output is read (FMI's
        <InitialUnknowns>: the same values as after Exit, bit for bit)."""
        self.validate_parameters()
        try:
            self.initialize()
        except ValueError as err:  # the models' consistency checks (ParameterError)
            raise RefusedValueError(str(err)) from err

    def do_step(self, current_time: float, step_size: float) -> bool:
        # the runtime refuses steps before initialisation, after a discard and of size <= 0
        if abs(current_time - self._time) > 1e-9 * max(1.0, abs(self._time)):
            self.fail(
                f"doStep at t = {current_time!r} s is invalid: expected the current time "
                f"{self._time!r} s"
            )
        ok = self.step(current_time, step_size)
        if ok:
            self._time = current_time + step_size
        else:
            self._discarded = True
        return ok

    def discard(self, message: str) -> bool:
        """Log a clean stop (e.g. a stall) and return False (fmi2Discard)."""
        self.log(f"{self.instance_name}: {message}", Fmi2Status.discard)
        return False

    def initialize(self) -> None:  # pragma: no cover - overridden
        """Compute the initial state from the parameters."""

    def step(self, t: float, h: float) -> bool:  # pragma: no cover - overridden
        """Advance from ``t`` by ``h``; return False to stop cleanly."""
        raise NotImplementedError

    # ---------------------------------------------------------------- state
    def _get_fmu_state(self) -> dict[str, Any]:
        state = {v.name: getattr(self, v.name) for v in self.VARIABLES}
        for name in ("_initialized", "_in_init", "_time", "_discarded", *self.INTERNAL_STATE):
            state[name] = copy.deepcopy(getattr(self, name))
        return state

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        for name, value in state.items():
            setattr(self, name, copy.deepcopy(value))
        self._last_get = (None, None)  # the next get checks the mode (_in_init) again

    def _fmu_state_to_bytes(self, state: dict[str, Any]) -> bytes:
        return state_codec.dumps(state, self.STATE_MODULES)

    def _fmu_state_from_bytes(self, data: bytes) -> dict[str, Any]:
        state = state_codec.loads(data, self.STATE_MODULES)
        expected = {v.name for v in self.VARIABLES}
        expected.update(("_initialized", "_in_init", "_time", "_discarded", *self.INTERNAL_STATE))
        if set(state) != expected:
            missing = sorted(expected - set(state))[:5]
            extra = sorted(set(state) - expected)[:5]
            raise state_codec.StateCodecError(
                f"the state is not one of {type(self).__name__}: missing {missing}, "
                f"unexpected {extra}"
            )
        return state
