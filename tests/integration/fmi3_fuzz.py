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
returned a status (0-4) or, for an instantiate, an instance or NULL; 1 otherwise.
"""

from __future__ import annotations

import collections
import ctypes
import math
import random
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

sys.path.insert(0, str(Path(__file__).parent))

from glider_cosim.master.instance import _extracted

CATEGORIES = [b"logAll", b"logStatusError", b"logStatusWarning", b"logFmiCalls", b"nope", None]
REALS = [0.0, 1.0, -1.0, 0.02, 1e308, -1e308, math.inf, -math.inf, math.nan, 5e-324, 1e-3]
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

    def instantiate(self, name: bytes | None = b"x", logging: bool = False, **odd) -> int | None:
        return self.dll.fmi3InstantiateCoSimulation(
            name, odd.get("token", self.md.guid.encode()), odd.get("resources", self.resources),
            False, logging, odd.get("event", False), odd.get("early", False), None, 0, None,
            self.log, None,
        )  # fmt: skip

    def initialize(self, c) -> int:
        st = self.dll.fmi3EnterInitializationMode(c, False, 0.0, 0.0, False, 0.0)
        return max(st, self.dll.fmi3ExitInitializationMode(c))


class Fuzzer3:
    def __init__(self, raw: Raw3, rng: random.Random):
        self.raw, self.rng = raw, rng
        self.counts: collections.Counter = collections.Counter()
        self.live: list[int] = []
        self.freed: list[int] = []
        self.states: list[c_void_p] = []
        self.blobs: list[bytes] = []
        self.nvars = len(raw.md.modelVariables)
        self.by_type: dict[str, list[int]] = collections.defaultdict(list)
        for v in raw.md.modelVariables:
            if v.causality in ("input", "output") or self.rng.random() < 0.2:
                self.by_type[v.type].append(v.valueReference)
        self.t: dict[int, float] = {}

    # ------------------------------------------------------------ arguments
    def comp(self):
        r = self.rng.random()
        if r < 0.85 and self.live:
            return self.rng.choice(self.live)
        if r < 0.95 and self.freed:
            return self.rng.choice(self.freed)
        return None

    def refs(self, typ: str = "Float64"):
        n = self.rng.choice([0, 1, 1, 2, 3, 5])
        if n and self.rng.random() < 0.05:
            return None, n
        pool = self.by_type.get(typ) or [0]
        if self.rng.random() < 0.2:
            pool = [self.rng.randrange(self.nvars + 1), self.nvars + 1, 10**6, 2**32 - 1]
        return (c_uint * max(n, 1))(*(self.rng.choice(pool) for _ in range(max(n, 1)))), n

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

    def time(self):
        return self.rng.choice([0.0, 0.02, 0.04, -1.0, math.nan, math.inf, 1e9])

    def flags(self, k: int):
        """k output flags (fmi3Boolean*), each NULL now and then."""
        return [None if self.rng.random() < 0.1 else ctypes.byref(c_bool()) for _ in range(k)]

    # ------------------------------------------------------------ calls
    def call(self) -> tuple[str, object]:
        raw, rng = self.raw, self.rng
        kind = rng.choice([
            "instantiate", "instantiate_odd", "other_kinds", "free", "enter", "exit", "step",
            "step", "step", "terminate", "reset", "get", "get", "set", "set", "debug",
            "getstate", "setstate", "freestate", "serialize", "deserialize", "modes",
            "dependencies", "derivatives", "discrete", "init", "init", "init", "step", "step",
            "get", "reset",
        ])  # fmt: skip
        c = self.comp()
        if kind == "instantiate":
            h = raw.instantiate(f"f{len(self.live)}".encode(), logging=rng.random() < 0.3)
            if h:
                self.live.append(h)
            return kind, None
        if kind == "instantiate_odd":
            odd = rng.choice([{"event": True}, {"early": True}, {"token": b"{not-ours}"},
                              {"token": None}, {"resources": None}, {"resources": b"/nope/"},
                              {}])  # fmt: skip
            h = raw.instantiate(rng.choice([None, b"", b"odd"]), **odd)
            if h:
                self.live.append(h)
            return kind, None
        if kind == "other_kinds":
            if rng.random() < 0.5:
                h = raw.dll.fmi3InstantiateModelExchange(b"me", raw.md.guid.encode(),
                                                         raw.resources, False, False, None,
                                                         raw.log)  # fmt: skip
            else:
                h = raw.dll.fmi3InstantiateScheduledExecution(
                    b"se",
                    raw.md.guid.encode(),
                    raw.resources,
                    False,
                    False,
                    None,
                    raw.log,
                    None,
                    None,
                    None,
                )
            if h:
                self.live.append(h)
            return kind, None
        if kind == "free":
            if c in self.live:
                self.live.remove(c)
                self.freed.append(c)
            raw.FreeInstance(c)
            return kind, None
        if kind == "init":
            if c is None or c in self.freed:
                c = raw.instantiate(f"f{len(self.live)}".encode(), logging=rng.random() < 0.3)
                if not c:
                    return kind, None
                self.live.append(c)
            self.t[c] = 0.0
            return kind, raw.initialize(c)
        if kind == "enter":
            return kind, raw.EnterInitializationMode(
                c, rng.random() < 0.5, rng.choice(REALS), self.time(), rng.random() < 0.5,
                self.time(),
            )  # fmt: skip
        if kind == "exit":
            return kind, raw.ExitInitializationMode(c)
        if kind == "step":
            h = rng.choice([0.02, 0.02, 0.02, 0.02, 0.0, -0.02, math.nan, math.inf, 1e-9, 10.0])
            t = self.t.get(c, 0.0) if rng.random() < 0.8 else self.time()
            last = None if rng.random() < 0.1 else ctypes.byref(c_double())
            st = raw.DoStep(c, t, h, rng.random() < 0.5, *self.flags(3), last)
            if st == 0:
                self.t[c] = t + h
            return kind, st
        if kind == "terminate":
            return kind, raw.Terminate(c)
        if kind == "reset":
            return kind, raw.Reset(c)
        if kind in ("get", "set"):
            typ = rng.choice(["Float64"] * 4 + ["Int32"] * 2 + ["Boolean"] * 2 + list(TYPES))
            ctype = TYPES[typ]
            vr, n = self.refs(typ)
            nv = self.n_values(n)
            size = max(n, nv, 1)
            if kind == "get":
                out = None if rng.random() < 0.08 else (ctype * size)()
                return f"get{typ}", getattr(raw, f"Get{typ}")(c, vr, n, out, nv)
            return f"set{typ}", getattr(raw, f"Set{typ}")(c, vr, n, self.values(ctype, size), nv)
        if kind == "debug":
            n = rng.randint(0, 3)
            cats = None if (n and rng.random() < 0.1) else (c_char_p * max(n, 1))(
                *(rng.choice(CATEGORIES) for _ in range(max(n, 1))))  # fmt: skip
            return kind, raw.SetDebugLogging(c, rng.random() < 0.5, n, cats)
        if kind == "getstate":
            s = c_void_p() if rng.random() < 0.7 or not self.states else rng.choice(self.states)
            st = raw.GetFMUState(c, ctypes.byref(s))
            if st == 0 and s.value and s not in self.states:
                self.states.append(s)
            return kind, st
        if kind == "setstate":
            s = rng.choice(self.states) if self.states and rng.random() < 0.8 else c_void_p(77)
            return kind, raw.SetFMUState(c, s)
        if kind == "freestate":
            s = rng.choice(self.states) if self.states else c_void_p()
            st = raw.FreeFMUState(c, ctypes.byref(s))
            if s.value is None:
                self.states = [x for x in self.states if x.value is not None and x is not s]
            return kind, st
        if kind == "serialize":
            s = rng.choice(self.states) if self.states else c_void_p(99)
            size = c_size_t()
            st = raw.SerializedFMUStateSize(c, s, ctypes.byref(size))
            if st == 0:
                n = max(size.value - (1 if rng.random() < 0.2 else 0), 0)
                buf = ctypes.create_string_buffer(max(n, 1))
                st = raw.SerializeFMUState(c, s, buf, n)
                if st == 0:
                    self.blobs.append(buf.raw[:n])
            return kind, st
        if kind == "deserialize":
            blob = rng.choice(self.blobs) if self.blobs and rng.random() < 0.6 else b""
            if blob and rng.random() < 0.5:
                i = rng.randrange(len(blob))
                blob = blob[:i] + bytes([rng.randrange(256)]) + blob[i + 1 :]
            if rng.random() < 0.3:
                blob = bytes(rng.randrange(256) for _ in range(rng.choice([0, 8, 300, 2000])))
            s = c_void_p()
            st = raw.DeserializeFMUState(c, blob, len(blob), ctypes.byref(s))
            if st == 0 and s.value:
                self.states.append(s)
            return kind, st
        if kind == "modes":
            which = rng.choice(["EnterEventMode", "EnterStepMode", "EnterConfigurationMode",
                                "ExitConfigurationMode", "EvaluateDiscreteStates",
                                "EnterContinuousTimeMode"])  # fmt: skip
            return which, getattr(raw, which)(c)
        if kind == "dependencies":
            vr = rng.choice(self.by_type.get("Float64") or [0]) if rng.random() < 0.8 else 10**6
            if rng.random() < 0.5:
                n = c_size_t()
                return "ndeps", raw.GetNumberOfVariableDependencies(c, vr, ctypes.byref(n))
            k = rng.choice([0, 1, 3])
            arrays = [(c_size_t * max(k, 1))(), (c_uint * max(k, 1))(), (c_size_t * max(k, 1))(),
                      (c_int * max(k, 1))()]  # fmt: skip
            return "deps", raw.GetVariableDependencies(c, vr, *arrays, k)
        if kind == "derivatives":
            vr, n = self.refs()
            which = rng.choice(["GetDirectionalDerivative", "GetAdjointDerivative"])
            if rng.random() < 0.3:
                orders = (c_int32 * max(n, 1))(1)
                out = (c_double * max(n, 1))()
                return "outder", raw.GetOutputDerivatives(c, vr, n, orders, out, n)
            seed, sens = (c_double * max(n, 1))(), (c_double * max(n, 1))()
            return which, getattr(raw, which)(c, vr, n, vr, n, seed, n, sens, n)
        # discrete: updateDiscreteStates, intervals, clocks, binaries, set time
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

    def sequence(self) -> str | None:
        for _ in range(self.rng.randint(5, 40)):
            name, status = self.call()
            self.counts[name, status] += 1
            if status is not None and status not in (0, 1, 2, 3, 4):
                return f"{name} returned {status!r}"
        if self.rng.random() < 0.7:
            for c in self.live:
                self.raw.FreeInstance(c)
            self.freed += self.live
            self.live, self.states = [], []
        return None


def main(argv: list[str]) -> int:
    seed, count, fmus = int(argv[0]), int(argv[1]), argv[2:]
    for fmu in fmus:
        raw = Raw3(Path(fmu))
        rng = random.Random(f"{seed}:fmi3:{Path(fmu).stem}")
        fuzzer = Fuzzer3(raw, rng)
        for i in range(count):
            print(f"sequence {Path(fmu).stem} {i} {seed}", flush=True)
            problem = fuzzer.sequence()
            if problem:
                print(f"FAILED {Path(fmu).stem} sequence {i} seed {seed}: {problem}", flush=True)
                return 1
            raw.messages.clear()
        for c in fuzzer.live:
            raw.FreeInstance(c)
        ok_steps = fuzzer.counts["step", 0]
        errors = sum(n for (_, st), n in fuzzer.counts.items() if st == 3)
        print(f"{Path(fmu).stem}: {sum(fuzzer.counts.values())} calls, {ok_steps} steps OK, "
              f"{errors} fmi3Error", flush=True)  # fmt: skip
    print("done", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
