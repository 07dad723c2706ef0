"""Random FMI 3.0 call sequences made twice: on an FMU's WebAssembly component (FMI-LS-WASM,
through wasmtime) and on the same FMU's native library; both must agree.

Usage: python tests/integration/wasm_fuzz.py SEED SEQUENCES FMU [FMU ...]

The differential twin of ``fmi3_fuzz.py`` (its ``Raw3`` drives the library, its argument
pools and sequence loop are ``fuzz_common.py``'s): each call is drawn once as the draft's
WIT call (lists, options, one resource per instance) and made on the component and, in
the C terms the glue ``src/fmi/wasm/fmi3_wasm.c`` maps it to, on the library. Every call
must return the same status on both, with the same log messages (status and text), and a
getter that succeeds the same values (equal, or within 1e-12 for Float64/Float32: the
component's libm is WASI libc's). What the WIT cannot express (NULL arrays, freed or forged
instances, nValues of a getter other than the references') is fmi3_fuzz.py's alone.
Exit 0 when every call agreed, 1 naming the first that did not.
"""

from __future__ import annotations

import ctypes
import math
import sys
from ctypes import c_bool, c_char_p, c_double, c_size_t, c_uint, c_void_p
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from fmi3_fuzz import TYPES, Raw3  # noqa: E402
from fuzz_common import CATEGORIES, REALS, FuzzerBase, main  # noqa: E402

from glider_cosim.master.wasm import STATUS, WasmAdapter  # noqa: E402

WIT_TYPE = {"Float64": "float64", "Float32": "float32", "Int8": "int8", "UInt8": "uint8",
            "Int16": "int16", "UInt16": "uint16", "Int32": "int32", "UInt32": "uint32",
            "Int64": "int64", "UInt64": "uint64", "Boolean": "boolean",
            "String": "string"}  # fmt: skip


MODES = [("EnterEventMode", "enter-event-mode"), ("EnterStepMode", "enter-step-mode"),
         ("EnterConfigurationMode", "enter-configuration-mode"),
         ("ExitConfigurationMode", "exit-configuration-mode"),
         ("EvaluateDiscreteStates", "evaluate-discrete-states")]  # fmt: skip


class Mismatch(AssertionError):
    """The component and the library disagreed."""


class Twin:
    """An FMU's component and native library, called alike; the instances are numbered."""

    def __init__(self, fmu: Path):
        self.raw = Raw3(fmu)
        self.md = self.raw.md
        ident = self.md.coSimulation.modelIdentifier
        self.wasm = WasmAdapter(self.md.guid, str(self.raw.dir), ident, "fuzz")
        self.wasm_messages: list[tuple[int, bytes]] = []
        self.wasm._log = lambda env, st, cat, msg: self.wasm_messages.append((st, msg))
        self.messages = self.raw.messages
        self.pairs: dict[int, tuple[int, object]] = {}  # handle -> (library's, component's)
        self.last = ""
        self.count = 0

    # ------------------------------------------------------------ comparing
    def agree(self, what: str, native: object, component: object) -> None:
        self.last = what
        if native != component:
            raise Mismatch(f"{what}: library {native!r}, component {component!r}")
        if self.messages != self.wasm_messages:
            raise Mismatch(f"{what}: messages differ: library {self.messages!r}, component "
                           f"{self.wasm_messages!r}")  # fmt: skip
        self.messages.clear()
        self.wasm_messages.clear()

    def on(self, c: int, wit: str, *args):
        return self.wasm.method(self.pairs[c][1], wit, *args)

    @staticmethod
    def status(result: object) -> int:
        return STATUS[result] if isinstance(result, str) else 0

    # ------------------------------------------------------------ instances
    def instantiate(self, name: str = "x", logging: bool = False, **odd) -> int | None:
        token = odd.get("token", self.md.guid)
        native = self.raw.instantiate(name.encode(), logging, token=token.encode(),
                                      event=odd.get("event", False),
                                      early=odd.get("early", False))  # fmt: skip
        comp = self.wasm.method(None, "[static]co-simulation-instance.instantiate-co-simulation",
                                name, token, "", False, logging, odd.get("event", False),
                                odd.get("early", False), [])  # fmt: skip
        self.agree(f"instantiate({name!r}, {odd})", native is None, comp is None)
        if native is None:
            return None
        self.count += 1
        handle = self.count
        self.pairs[handle] = (native, comp)
        return handle

    def FreeInstance(self, c) -> None:
        if c not in self.pairs:
            return
        native, comp = self.pairs.pop(c)
        self.raw.FreeInstance(native)
        comp.drop(self.wasm.store)
        self.agree("free", None, None)

    def initialize(self, c) -> int:
        st = self.simple(c, "EnterInitializationMode", "enter", (False, 0.0, 0.0, False, 0.0),
                         (None, 0.0, None))  # fmt: skip
        return max(st, self.simple(c, "ExitInitializationMode", "exit-initialization-mode"))

    def simple(self, c, fn: str, wit: str, c_args=(), wit_args=()) -> int:
        wit = "enter-initialization-mode" if wit == "enter" else wit
        native = getattr(self.raw, fn)(self.pairs[c][0], *c_args)
        comp = self.status(self.on(c, wit, *wit_args))
        self.agree(fn, native, comp)
        return native


def close(a: float, b: float) -> bool:
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    return a == b or abs(a - b) <= 1e-12 * (1 + abs(a))


class WasmFuzzer(FuzzerBase):
    KINDS = [
        "instantiate", "instantiate_odd", "free", "enter", "exit", "step", "step", "step",
        "terminate", "reset", "get", "get", "set", "set", "debug", "getstate", "setstate",
        "modes", "dependencies", "derivatives", "discrete", "init", "init", "init", "step",
        "step", "get", "reset", "run", "run",
    ]  # fmt: skip
    REAL = "Float64"
    VR_SLACK = 1
    ERROR = "fmi3Error"

    def call_run(self, c):
        """The proper sequence on a fresh instance, then steps with its inputs set and
        its outputs read: the states after stepping, and values to compare."""
        c = self.raw.instantiate(f"run{len(self.live)}", logging=self.rng.random() < 0.3)
        if c is None:
            return "run", None
        self.live.append(c)
        self.t[c] = 0.0
        st = self.raw.initialize(c)
        inputs = [v.valueReference for v in self.raw.md.modelVariables
                  if v.causality == "input" and v.type == "Float64"]  # fmt: skip
        outputs = [v.valueReference for v in self.raw.md.modelVariables
                   if v.causality == "output" and v.type == "Float64"]  # fmt: skip
        twin = self.raw
        for _ in range(self.rng.randint(1, 8)):
            if st > 1:
                break
            vals = [self.rng.gauss(0, 0.05) for _ in inputs]
            array = (c_double * max(len(vals), 1))(*vals)
            native = twin.raw.SetFloat64(twin.pairs[c][0], self.vr_array(inputs), len(inputs),
                                         array, len(vals))  # fmt: skip
            twin.agree("run: set-float64", native,
                       twin.status(twin.on(c, "set-float64", inputs, vals)))  # fmt: skip
            st = self.do_step(c, self.t[c], 0.02)
            self.counts["step", st] += 1
            if st == 0:
                self.t[c] += 0.02
            out = (c_double * max(len(outputs), 1))()
            native = twin.raw.GetFloat64(twin.pairs[c][0], self.vr_array(outputs), len(outputs),
                                         out, len(outputs))  # fmt: skip
            got = twin.on(c, "get-float64", outputs)
            twin.agree("run: get-float64", native, twin.status(got))
            if native <= 1 and not all(map(close, list(out[: len(outputs)]), got)):
                raise Mismatch(f"run: outputs: library {list(out)}, component {got}")
        return "run", st

    def comp(self):
        return self.rng.choice(self.live) if self.live else None

    def call(self):
        kind = self.rng.choice(self.KINDS)
        c = self.comp()
        if c is None and kind not in ("instantiate", "instantiate_odd", "init"):
            kind = "instantiate"
        return getattr(self, f"call_{kind}")(c)

    def refs(self, typ: str | None = None):
        vr, n = super().refs(typ)
        return ([] if vr is None or n == 0 else list(vr[:n])), n

    def boolean(self):
        return self.rng.random() < 0.5

    def values(self, typ: str, size: int) -> list:
        rng = self.rng
        if typ in ("Float64", "Float32"):
            return [rng.choice(REALS) if rng.random() < 0.2 else rng.gauss(0, 0.1)
                    for _ in range(size)]  # fmt: skip
        if typ == "Boolean":
            return [rng.random() < 0.5 for _ in range(size)]
        if typ == "String":
            return [rng.choice(["", "x", "%s%n%d", "é"]) for _ in range(size)]
        ctype = TYPES[typ]
        bits = 8 * ctypes.sizeof(ctype)
        signed = ctype(-1).value < 0
        lo, hi = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else (0, 2**bits - 1)
        return [rng.choice([0, 1, 2, 3, lo, hi]) for _ in range(size)]

    @staticmethod
    def vr_array(vr: list[int]):
        return (c_uint * max(len(vr), 1))(*vr)

    # ------------------------------------------------------------ calls
    def call_instantiate_odd(self, c):
        odd = self.rng.choice([{"event": True}, {"early": True}, {"token": "{not-ours}"}, {}])
        h = self.raw.instantiate(self.rng.choice(["", "odd"]), **odd)
        if h:
            self.live.append(h)
        return "instantiate_odd", None

    def call_exit(self, c):
        return "exit", self.raw.simple(c, "ExitInitializationMode", "exit-initialization-mode")

    def call_terminate(self, c):
        return "terminate", self.raw.simple(c, "Terminate", "terminate")

    def call_reset(self, c):
        return "reset", self.raw.simple(c, "Reset", "reset")

    def call_modes(self, c):
        which = self.rng.choice(MODES)
        return which[0], self.raw.simple(c, *which)

    def call_enter(self, c):
        rng = self.rng
        tol_on, tol, start = rng.random() < 0.5, rng.choice(REALS), self.time()
        stop_on, stop = rng.random() < 0.5, self.time()
        wit_args = (tol if tol_on else None, start, stop if stop_on else None)
        st = self.raw.simple(c, "EnterInitializationMode", "enter",
                             (tol_on, tol, start, stop_on, stop), wit_args)  # fmt: skip
        return "enter", st

    def call_debug(self, c):
        rng, twin = self.rng, self.raw
        names = [rng.choice(CATEGORIES) or b"nope" for _ in range(rng.randint(0, 3))]
        on = self.boolean()
        cats = (c_char_p * max(len(names), 1))(*names)
        native = twin.raw.SetDebugLogging(twin.pairs[c][0], on, len(names), cats)
        comp = twin.status(twin.on(c, "set-debug-logging", on, [n.decode() for n in names]))
        twin.agree(f"set-debug-logging({on}, {names})", native, comp)
        return "debug", native

    def do_step(self, c, t, h):
        twin = self.raw
        no_set = self.boolean()
        flags = [c_bool() for _ in range(3)]
        last = c_double()
        native = twin.raw.DoStep(twin.pairs[c][0], t, h, no_set,
                                 *(ctypes.byref(f) for f in flags), ctypes.byref(last))  # fmt: skip
        out = twin.on(c, "do-step", t, h, no_set)
        comp = twin.status(out)
        twin.agree(f"do-step({t}, {h})", native, comp)
        if native <= 1:
            got = (getattr(out, "last-successful-time"), getattr(out, "terminate-simulation"))
            want = (last.value, flags[1].value)
            if not (close(want[0], got[0]) and want[1] == got[1]):
                raise Mismatch(f"do-step({t}, {h}): library {want}, component {got}")
        return native

    def call_get(self, c):
        twin = self.raw
        typ = self.rng.choice(["Float64"] * 4 + ["Int32"] * 2 + ["Boolean"] * 2 + list(TYPES))
        vr, n = self.refs(typ)
        out = (TYPES[typ] * max(n, 1))()
        native = getattr(twin.raw, f"Get{typ}")(twin.pairs[c][0], self.vr_array(vr), len(vr),
                                                out, len(vr))  # fmt: skip
        got = twin.on(c, f"get-{WIT_TYPE[typ]}", vr)
        twin.agree(f"get-{WIT_TYPE[typ]}({vr})", native, twin.status(got))
        if native <= 1:
            want, got = list(out[: len(vr)]), list(got)
            if typ == "String":
                want = [(w or b"").decode() for w in want]
            if len(want) != len(got) or not all(map(close, want, got)):
                raise Mismatch(f"get-{WIT_TYPE[typ]}({vr}): library {want}, component {got}")
        return f"get{typ}", native

    def call_set(self, c):
        twin, rng = self.raw, self.rng
        typ = self.rng.choice(["Float64"] * 4 + ["Int32"] * 2 + ["Boolean"] * 2 + list(TYPES))
        vr, n = self.refs(typ)
        nv = len(vr) if rng.random() < 0.8 else rng.choice([0, max(len(vr) - 1, 0), len(vr) + 1])
        vals = self.values(typ, max(len(vr), nv))
        cvals = [v.encode() for v in vals] if typ == "String" else vals
        array = (TYPES[typ] * max(len(cvals), 1))(*cvals)
        native = getattr(twin.raw, f"Set{typ}")(twin.pairs[c][0], self.vr_array(vr), len(vr),
                                                array, nv)  # fmt: skip
        if typ == "Float32":  # what the library got: the values as C floats
            vals = list(array)
        wit_vals = bytes(vals[:nv]) if typ == "UInt8" else vals[:nv]  # list<u8>: bytes
        comp = twin.status(twin.on(c, f"set-{WIT_TYPE[typ]}", vr, wit_vals))
        twin.agree(f"set-{WIT_TYPE[typ]}({vr}, {vals[:nv]})", native, comp)
        return f"set{typ}", native

    def call_getstate(self, c):
        """get-fmu-state: fmi3GetFMUState, fmi3SerializedFMUStateSize, fmi3SerializeFMUState,
        fmi3FreeFMUState on the library."""
        twin, raw = self.raw, self.raw.raw
        p = twin.pairs[c][0]
        s, size = c_void_p(), c_size_t()
        st = raw.GetFMUState(p, ctypes.byref(s))
        blob = b""
        if st <= 1:
            st = raw.SerializedFMUStateSize(p, s, ctypes.byref(size))
        if st <= 1:
            buf = ctypes.create_string_buffer(max(size.value, 1))
            st = raw.SerializeFMUState(p, s, buf, size.value)
            blob = buf.raw[: size.value]
        if s.value:
            raw.FreeFMUState(p, ctypes.byref(s))
        got = twin.on(c, "get-fmu-state")
        twin.agree("get-fmu-state", st, twin.status(got))
        if st <= 1:
            self.blobs.append((blob, bytes(got)))
        return "getstate", st

    def call_setstate(self, c):
        twin, raw, rng = self.raw, self.raw.raw, self.rng
        blobs = rng.choice(self.blobs) if self.blobs and rng.random() < 0.8 else (b"", b"")
        if rng.random() < 0.3 and blobs[0]:  # damage both alike
            i, b = rng.randrange(len(blobs[0])), rng.randrange(256)
            blobs = tuple(x[:i] + bytes([b]) + x[i + 1 :] for x in blobs)
        p = twin.pairs[c][0]
        s = c_void_p()
        st = raw.DeserializeFMUState(p, blobs[0], len(blobs[0]), ctypes.byref(s))
        if st <= 1:
            st = raw.SetFMUState(p, s)
        if s.value:
            raw.FreeFMUState(p, ctypes.byref(s))
        twin.agree("set-fmu-state", st, twin.status(twin.on(c, "set-fmu-state", blobs[1])))
        return "setstate", st

    def call_dependencies(self, c):
        twin = self.raw
        vr = self.rng.choice(self.by_type.get("Float64") or [0])
        n = c_size_t()
        st = twin.raw.GetNumberOfVariableDependencies(twin.pairs[c][0], vr, ctypes.byref(n))
        got = twin.on(c, "get-number-of-variable-dependencies", vr)
        twin.agree("get-number-of-variable-dependencies", st, twin.status(got))
        return "ndeps", st

    def call_derivatives(self, c):
        twin, rng = self.raw, self.rng
        vr, n = self.refs()
        p, k = twin.pairs[c][0], len(vr)
        seed, sens = (c_double * max(k, 1))(), (c_double * max(k, 1))()
        which, wit = rng.choice([("GetDirectionalDerivative", "get-directional-derivative"),
                                 ("GetAdjointDerivative", "get-adjoint-derivative")])  # fmt: skip
        st = getattr(twin.raw, which)(p, self.vr_array(vr), k, self.vr_array(vr), k, seed, k,
                                      sens, k)  # fmt: skip
        got = twin.on(c, wit, vr, vr, [0.0] * k)
        twin.agree(wit, st, twin.status(got))
        return which, st

    def call_discrete(self, c):
        twin = self.raw
        p = twin.pairs[c][0]
        vr, n = self.refs()
        which = self.rng.choice(["update", "interval", "clock"])
        if which == "update":
            flags = [ctypes.byref(c_bool()) for _ in range(5)]
            st = twin.raw.UpdateDiscreteStates(p, *flags, ctypes.byref(c_double()))
            got = twin.on(c, "update-discrete-states")
            twin.agree("update-discrete-states", st, twin.status(got))
        elif which == "interval":
            out, q = (c_double * max(n, 1))(), (ctypes.c_int * max(n, 1))()
            st = twin.raw.GetIntervalDecimal(p, self.vr_array(vr), len(vr), out, q)
            twin.agree("get-interval-decimal", st,
                       twin.status(twin.on(c, "get-interval-decimal", vr)))  # fmt: skip
        else:
            vals = (c_bool * max(n, 1))()
            st = twin.raw.GetClock(p, self.vr_array(vr), len(vr), vals)
            twin.agree("get-clock", st, twin.status(twin.on(c, "get-clock", vr)))
        return which, st

    def sequence(self) -> str | None:
        try:
            return super().sequence()
        except Mismatch as err:
            return str(err)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:], Twin, WasmFuzzer, seed_tag="wasm:"))
