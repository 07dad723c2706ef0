"""Random FMI 3.0 call sequences on FMI 3.0 FMUs, in one process: every call must return
a status.

Usage: python tests/integration/fmi3_fuzz.py SEED SEQUENCES FMU [FMU ...]

The FMI 3.0 variant of ``fmi_fuzz.py``, on raw ctypes with the signatures of the FMI 3.0
headers fmpy ships (``fmpy/c-code/fmi3FunctionTypes.h``). For each FMU, SEQUENCES
sequences of 5-40 calls drawn at random: the co-simulation functions (instantiate with
valid and odd arguments, event mode and early return asked for, model exchange and
scheduled execution, enter/exit initialisation with any experiment, step/event/
configuration mode, doStep with NULL or real output flags, terminate, reset, free), the
getters and setters of every FMI 3 type (Float64, Int32, Boolean, String, and Float32,
the other integers, Binary, Clock that the FMUs have none of) with nValues equal to nvr
or not, the FMU state calls with real and forged states and blobs, variable
dependencies, directional and adjoint derivatives, output derivatives, intervals,
updateDiscreteStates; on live, freed and NULL instances, with valid and unknown value
references, nvr = 0 and NULL arrays. ``sequence FMU INDEX SEED`` is printed and flushed
before each sequence, so a crash names the sequence to replay. Exit 0 when every call
returned a status (0-4) or, for an instantiate, an instance or NULL; 1 otherwise. What
it shares with ``fmi_fuzz.py`` is in ``fuzz_common.py``.
"""

from __future__ import annotations

import ctypes
import sys
from ctypes import (
    CFUNCTYPE,
    POINTER,
    c_bool,
    c_char_p,
    c_double,
    c_float,
    c_int,
    c_int8,
    c_int16,
    c_int32,
    c_int64,
    c_size_t,
    c_uint,
    c_uint8,
    c_uint16,
    c_uint32,
    c_uint64,
    c_void_p,
)
from pathlib import Path

from fmpy import read_model_description

from glider_cosim.master.instance import _extracted

sys.path.insert(0, str(Path(__file__).parent))
from fuzz_common import REALS, FuzzerBase, main  # noqa: E402

LOG = CFUNCTYPE(None, c_void_p, c_int, c_char_p, c_char_p)
_VR = POINTER(c_uint)
_B = POINTER(c_bool)
#: the types of fmi3Get<T>/fmi3Set<T> with their C types
TYPES = {
    "Float64": c_double, "Float32": c_float, "Int8": c_int8, "UInt8": c_uint8,
    "Int16": c_int16, "UInt16": c_uint16, "Int32": c_int32, "UInt32": c_uint32,
    "Int64": c_int64, "UInt64": c_uint64, "Boolean": c_bool, "String": c_char_p,
}  # fmt: skip
_I = c_void_p  # fmi3Instance
_SIGNATURES = {
    "fmi3InstantiateCoSimulation": ([c_char_p, c_char_p, c_char_p, c_bool, c_bool, c_bool,
                                     c_bool, _VR, c_size_t, c_void_p, LOG, c_void_p], c_void_p),
    "fmi3InstantiateModelExchange": ([c_char_p, c_char_p, c_char_p, c_bool, c_bool, c_void_p,
                                      LOG], c_void_p),
    "fmi3InstantiateScheduledExecution": ([c_char_p, c_char_p, c_char_p, c_bool, c_bool,
                                           c_void_p, LOG, c_void_p, c_void_p, c_void_p],
                                          c_void_p),
    "fmi3FreeInstance": ([_I], None),
    "fmi3SetDebugLogging": ([_I, c_bool, c_size_t, POINTER(c_char_p)], c_int),
    "fmi3EnterInitializationMode": ([_I, c_bool, c_double, c_double, c_bool, c_double], c_int),
    "fmi3DoStep": ([_I, c_double, c_double, c_bool, _B, _B, _B, POINTER(c_double)], c_int),
    "fmi3GetBinary": ([_I, _VR, c_size_t, POINTER(c_size_t), POINTER(c_void_p), c_size_t],
                      c_int),
    "fmi3SetBinary": ([_I, _VR, c_size_t, POINTER(c_size_t), POINTER(c_void_p), c_size_t],
                      c_int),
    "fmi3GetClock": ([_I, _VR, c_size_t, _B], c_int),
    "fmi3SetClock": ([_I, _VR, c_size_t, _B], c_int),
    "fmi3GetNumberOfVariableDependencies": ([_I, c_uint, POINTER(c_size_t)], c_int),
    "fmi3GetVariableDependencies": ([_I, c_uint, POINTER(c_size_t), _VR, POINTER(c_size_t),
                                     POINTER(c_int), c_size_t], c_int),
    "fmi3GetFMUState": ([_I, POINTER(c_void_p)], c_int),
    "fmi3SetFMUState": ([_I, c_void_p], c_int),
    "fmi3FreeFMUState": ([_I, POINTER(c_void_p)], c_int),
    "fmi3SerializedFMUStateSize": ([_I, c_void_p, POINTER(c_size_t)], c_int),
    "fmi3SerializeFMUState": ([_I, c_void_p, c_char_p, c_size_t], c_int),
    "fmi3DeserializeFMUState": ([_I, c_char_p, c_size_t, POINTER(c_void_p)], c_int),
    "fmi3GetDirectionalDerivative": ([_I, _VR, c_size_t, _VR, c_size_t, POINTER(c_double),
                                      c_size_t, POINTER(c_double), c_size_t], c_int),
    "fmi3GetAdjointDerivative": ([_I, _VR, c_size_t, _VR, c_size_t, POINTER(c_double),
                                  c_size_t, POINTER(c_double), c_size_t], c_int),
    "fmi3GetOutputDerivatives": ([_I, _VR, c_size_t, POINTER(c_int32), POINTER(c_double),
                                  c_size_t], c_int),
    "fmi3GetIntervalDecimal": ([_I, _VR, c_size_t, POINTER(c_double), POINTER(c_int)], c_int),
    "fmi3UpdateDiscreteStates": ([_I, _B, _B, _B, _B, _B, POINTER(c_double)], c_int),
    "fmi3SetTime": ([_I, c_double], c_int),
    "fmi3GetNumberOfContinuousStates": ([_I, POINTER(c_size_t)], c_int),
}  # fmt: skip
for _name in ("ExitInitializationMode", "EnterEventMode", "Terminate", "Reset", "EnterStepMode",
              "EnterConfigurationMode", "ExitConfigurationMode", "EvaluateDiscreteStates",
              "EnterContinuousTimeMode"):  # fmt: skip
    _SIGNATURES[f"fmi3{_name}"] = ([_I], c_int)
for _t, _ct in TYPES.items():
    _SIGNATURES[f"fmi3Get{_t}"] = ([_I, _VR, c_size_t, POINTER(_ct), c_size_t], c_int)
    _SIGNATURES[f"fmi3Set{_t}"] = ([_I, _VR, c_size_t, POINTER(_ct), c_size_t], c_int)


class Raw3:
    """An FMI 3.0 FMU's binary on ctypes (nothing checked, every status returned)."""

    def __init__(self, fmu: Path):
        self.md = read_model_description(str(fmu))
        self.dir = Path(_extracted(Path(fmu)))
        ident = self.md.coSimulation.modelIdentifier
        self.dll = ctypes.CDLL(str(self.dir / "binaries" / "x86_64-linux" / f"{ident}.so"))
        for name, (args, res) in _SIGNATURES.items():
            f = getattr(self.dll, name)
            f.argtypes, f.restype = args, res
        self.messages: list[tuple[int, bytes]] = []
        self.log = LOG(lambda env, st, cat, msg: self.messages.append((st, msg or b"")))
        self.resources = (str(self.dir / "resources") + "/").encode()

    def __getattr__(self, name: str):
        return getattr(self.dll, f"fmi3{name}")

    def instantiate(self, name: str | bytes | None = b"x", logging: bool = False, **odd):
        if isinstance(name, str):
            name = name.encode()
        return self.dll.fmi3InstantiateCoSimulation(
            name, odd.get("token", self.md.guid.encode()), odd.get("resources", self.resources),
            False, logging, odd.get("event", False), odd.get("early", False), None, 0, None,
            self.log, None,
        )  # fmt: skip

    def initialize(self, c) -> int:
        st = self.dll.fmi3EnterInitializationMode(c, False, 0.0, 0.0, False, 0.0)
        return max(st, self.dll.fmi3ExitInitializationMode(c))


class Fuzzer3(FuzzerBase):
    KINDS = [
        "instantiate", "instantiate_odd", "other_kinds", "free", "enter", "exit", "step",
        "step", "step", "terminate", "reset", "get", "get", "set", "set", "debug",
        "getstate", "setstate", "freestate", "serialize", "deserialize", "modes",
        "dependencies", "derivatives", "discrete", "init", "init", "init", "step", "step",
        "get", "reset",
    ]  # fmt: skip
    REAL = "Float64"
    VR_SLACK = 1
    STATE = "FMUState"
    DESERIALIZE = "DeserializeFMUState"
    ERROR = "fmi3Error"
    FOREIGN = b"fmi2"

    # ------------------------------------------------------------ arguments
    def n_values(self, n: int) -> int:
        """nValues: nvr mostly, sometimes another count (the array holds either)."""
        return n if self.rng.random() < 0.8 else self.rng.choice([0, max(n - 1, 0), n + 1, 7])

    def values(self, ctype, size: int):
        if self.rng.random() < 0.08:
            return None
        rng = self.rng
        if ctype in (c_double, c_float):
            vals = [rng.choice(REALS) if rng.random() < 0.2 else rng.gauss(0, 0.1)
                    for _ in range(size)]  # fmt: skip
        elif ctype is c_bool:
            vals = [rng.random() < 0.5 for _ in range(size)]
        elif ctype is c_char_p:
            vals = [rng.choice([b"", b"x", b"%s%n%d", "é".encode(), None]) for _ in range(size)]
        else:
            bits = 8 * ctypes.sizeof(ctype)
            signed = ctype(-1).value < 0
            lo, hi = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else (0, 2**bits - 1)
            vals = [rng.choice([0, 1, 2, 3, lo, hi]) for _ in range(size)]
        return (ctype * size)(*vals)

    def flags(self, k: int):
        """k output flags (fmi3Boolean*), each NULL now and then."""
        return [None if self.rng.random() < 0.1 else ctypes.byref(c_bool()) for _ in range(k)]

    def boolean(self):
        return self.rng.random() < 0.5

    def do_step(self, c, t, h):
        last = None if self.rng.random() < 0.1 else ctypes.byref(c_double())
        return self.raw.DoStep(c, t, h, self.boolean(), *self.flags(3), last)

    # ------------------------------------------------------------ calls
    def call_instantiate_odd(self, c):
        rng = self.rng
        odd = rng.choice([{"event": True}, {"early": True}, {"token": b"{not-ours}"},
                          {"token": None}, {"resources": None}, {"resources": b"/nope/"},
                          {}])  # fmt: skip
        h = self.raw.instantiate(rng.choice([None, b"", b"odd"]), **odd)
        if h:
            self.live.append(h)
        return "instantiate_odd", None

    def call_other_kinds(self, c):
        raw = self.raw
        if self.rng.random() < 0.5:
            h = raw.dll.fmi3InstantiateModelExchange(b"me", raw.md.guid.encode(), raw.resources,
                                                     False, False, None, raw.log)  # fmt: skip
        else:
            h = raw.dll.fmi3InstantiateScheduledExecution(
                b"se", raw.md.guid.encode(), raw.resources, False, False, None, raw.log, None,
                None, None,
            )  # fmt: skip
        if h:
            self.live.append(h)
        return "other_kinds", None

    def call_enter(self, c):
        rng = self.rng
        return "enter", self.raw.EnterInitializationMode(
            c, rng.random() < 0.5, rng.choice(REALS), self.time(), rng.random() < 0.5,
            self.time(),
        )  # fmt: skip

    def typed(self):
        typ = self.rng.choice(["Float64"] * 4 + ["Int32"] * 2 + ["Boolean"] * 2 + list(TYPES))
        vr, n = self.refs(typ)
        nv = self.n_values(n)
        return typ, TYPES[typ], vr, n, nv, max(n, nv, 1)

    def call_get(self, c):
        typ, ctype, vr, n, nv, size = self.typed()
        out = None if self.rng.random() < 0.08 else (ctype * size)()
        return f"get{typ}", getattr(self.raw, f"Get{typ}")(c, vr, n, out, nv)

    def call_set(self, c):
        typ, ctype, vr, n, nv, size = self.typed()
        return f"set{typ}", getattr(self.raw, f"Set{typ}")(c, vr, n, self.values(ctype, size), nv)

    def call_modes(self, c):
        which = self.rng.choice(["EnterEventMode", "EnterStepMode", "EnterConfigurationMode",
                                 "ExitConfigurationMode", "EvaluateDiscreteStates",
                                 "EnterContinuousTimeMode"])  # fmt: skip
        return which, getattr(self.raw, which)(c)

    def call_dependencies(self, c):
        raw, rng = self.raw, self.rng
        vr = rng.choice(self.by_type.get("Float64") or [0]) if rng.random() < 0.8 else 10**6
        if rng.random() < 0.5:
            n = c_size_t()
            return "ndeps", raw.GetNumberOfVariableDependencies(c, vr, ctypes.byref(n))
        k = rng.choice([0, 1, 3])
        arrays = [(c_size_t * max(k, 1))(), (c_uint * max(k, 1))(), (c_size_t * max(k, 1))(),
                  (c_int * max(k, 1))()]  # fmt: skip
        return "deps", raw.GetVariableDependencies(c, vr, *arrays, k)

    def call_derivatives(self, c):
        raw, rng = self.raw, self.rng
        vr, n = self.refs()
        which = rng.choice(["GetDirectionalDerivative", "GetAdjointDerivative"])
        if rng.random() < 0.3:
            orders = (c_int32 * max(n, 1))(1)
            out = (c_double * max(n, 1))()
            return "outder", raw.GetOutputDerivatives(c, vr, n, orders, out, n)
        seed, sens = (c_double * max(n, 1))(), (c_double * max(n, 1))()
        return which, getattr(raw, which)(c, vr, n, vr, n, seed, n, sens, n)

    def call_discrete(self, c):
        """updateDiscreteStates, intervals, clocks, binaries, set time."""
        raw, rng = self.raw, self.rng
        which = rng.choice(["update", "interval", "clock", "binary", "time", "nstates"])
        vr, n = self.refs()
        if which == "update":
            return which, raw.UpdateDiscreteStates(c, *self.flags(5), ctypes.byref(c_double()))
        if which == "interval":
            out, q = (c_double * max(n, 1))(), (c_int * max(n, 1))()
            return which, raw.GetIntervalDecimal(c, vr, n, out, q)
        if which == "clock":
            vals = (c_bool * max(n, 1))()
            fn = raw.GetClock if rng.random() < 0.5 else raw.SetClock
            return which, fn(c, vr, n, vals)
        if which == "binary":
            sizes, ptrs = (c_size_t * max(n, 1))(), (c_void_p * max(n, 1))()
            fn = raw.GetBinary if rng.random() < 0.5 else raw.SetBinary
            return which, fn(c, vr, n, sizes, ptrs, n)
        if which == "time":
            return which, raw.SetTime(c, self.time())
        return which, raw.GetNumberOfContinuousStates(c, ctypes.byref(c_size_t()))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:], Raw3, Fuzzer3, seed_tag="fmi3:"))
