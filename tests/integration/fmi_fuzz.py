"""Random FMI call sequences on FMUs, in one process: every call must return a status.

Usage: python tests/integration/fmi_fuzz.py SEED SEQUENCES FMU [FMU ...]

For each FMU, SEQUENCES sequences of 5-40 calls drawn at random: every FMI 2.0
co-simulation function, in any order, on live, freed and NULL instances, with valid and
unknown value references, nvr = 0, NULL arrays, non-finite times and steps, odd values,
FMU states real and forged, known and unknown log categories. Before each sequence the
line ``sequence FMU INDEX SEED`` is printed and flushed, so a crash names the sequence to
replay (the same SEED and FMU reproduce it). Exit 0 when every call returned a status
(0-4) or, for fmi2Instantiate, an instance or NULL; 1 with the offending call otherwise.
A crash shows up as a signal.
"""

from __future__ import annotations

import collections
import ctypes
import math
import random
import sys
from ctypes import c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from raw_fmi import RawFMU  # noqa: E402

CATEGORIES = [b"logAll", b"logStatusError", b"logStatusWarning", b"logFmiCalls", b"nope", None]
REALS = [0.0, 1.0, -1.0, 0.02, 1e308, -1e308, math.inf, -math.inf, math.nan, 5e-324, 1e-3]


class Fuzzer:
    def __init__(self, raw: RawFMU, rng: random.Random):
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
        self.t: dict[int, float] = {}  # current time of instances that stepped fine

    # ------------------------------------------------------------ arguments
    def comp(self):
        r = self.rng.random()
        if r < 0.85 and self.live:
            return self.rng.choice(self.live)
        if r < 0.95 and self.freed:
            return self.rng.choice(self.freed)
        return None

    def refs(self, typ: str = "Real"):
        n = self.rng.choice([0, 1, 1, 2, 3, 5])
        if n and self.rng.random() < 0.05:
            return None, n
        pool = self.by_type.get(typ) or [0]
        if self.rng.random() < 0.2:  # anything, of any type or none
            pool = [self.rng.randrange(self.nvars), self.nvars, 10**6, 2**32 - 1]
        return (c_uint * max(n, 1))(*(self.rng.choice(pool) for _ in range(max(n, 1)))), n

    def values(self, ctype, n):
        if n and self.rng.random() < 0.08:
            return None
        if ctype is c_double:
            vals = [self.rng.choice(REALS) if self.rng.random() < 0.2 else self.rng.gauss(0, 0.1)
                    for _ in range(max(n, 1))]  # fmt: skip
        elif ctype is c_int:
            vals = [
                self.rng.choice([0, 1, 2, 3, -1, 2**31 - 1, -(2**31)]) for _ in range(max(n, 1))
            ]
        else:
            vals = [self.rng.choice([b"", b"x", b"%s%n%d", "é".encode(), None])
                    for _ in range(max(n, 1))]  # fmt: skip
        return (ctype * max(n, 1))(*vals)

    def time(self):
        return self.rng.choice([0.0, 0.02, 0.04, -1.0, math.nan, math.inf, 1e9])

    # ------------------------------------------------------------ calls
    def call(self) -> tuple[str, object]:
        raw, rng = self.raw, self.rng
        kind = rng.choice([
            "instantiate", "free", "setup", "enter", "exit", "step", "step", "step",
            "terminate", "reset", "get", "get", "set", "set", "debug", "getstate", "setstate",
            "freestate", "serialize", "deserialize", "status", "cancel", "directional",
            "init", "init", "init", "step", "step", "step", "get", "reset",
        ])  # fmt: skip
        c = self.comp()
        if kind == "instantiate":
            h = raw.instantiate(f"f{len(self.live)}", logging=rng.random() < 0.3)
            if h:
                self.live.append(h)
            return kind, None
        if kind == "free":
            if c in self.live:
                self.live.remove(c)
                self.freed.append(c)
            raw.FreeInstance(c)
            return kind, None
        if kind == "init":  # the proper sequence, to reach the states after it
            if c is None or c in self.freed:
                c = raw.instantiate(f"f{len(self.live)}", logging=rng.random() < 0.3)
                if not c:
                    return kind, None
                self.live.append(c)
            self.t[c] = 0.0
            return kind, raw.initialize(c)
        if kind == "setup":
            tol, start, stop = rng.choice(REALS), self.time(), self.time()
            return kind, raw.SetupExperiment(
                c, rng.randint(0, 1), tol, start, rng.randint(0, 1), stop
            )
        if kind == "enter":
            return kind, raw.EnterInitializationMode(c)
        if kind == "exit":
            return kind, raw.ExitInitializationMode(c)
        if kind == "step":
            h = rng.choice([0.02, 0.02, 0.02, 0.02, 0.0, -0.02, math.nan, math.inf, 1e-9, 10.0])
            t = self.t.get(c, 0.0) if rng.random() < 0.8 else self.time()
            st = raw.DoStep(c, t, h, rng.randint(0, 1))
            if st == 0:
                self.t[c] = t + h
            return kind, st
        if kind == "terminate":
            return kind, raw.Terminate(c)
        if kind == "reset":
            return kind, raw.Reset(c)
        if kind in ("get", "set"):
            typ = rng.choice(["Real", "Integer", "Boolean", "String"])
            ctype = {"Real": c_double, "Integer": c_int, "Boolean": c_int, "String": c_char_p}[typ]
            vr, n = self.refs(typ)
            if kind == "get":
                out = None if (n and rng.random() < 0.08) else (ctype * max(n, 1))()
                return f"get{typ}", getattr(raw, f"Get{typ}")(c, vr, n, out)
            return f"set{typ}", getattr(raw, f"Set{typ}")(c, vr, n, self.values(ctype, n))
        if kind == "debug":
            n = rng.randint(0, 3)
            cats = None if (n and rng.random() < 0.1) else (c_char_p * max(n, 1))(
                *(rng.choice(CATEGORIES) for _ in range(max(n, 1))))  # fmt: skip
            return kind, raw.SetDebugLogging(c, rng.randint(0, 1), n, cats)
        if kind == "getstate":
            s = c_void_p() if rng.random() < 0.7 or not self.states else rng.choice(self.states)
            st = raw.GetFMUstate(c, ctypes.byref(s))
            if st == 0 and s.value and s not in self.states:
                self.states.append(s)
            return kind, st
        if kind == "setstate":
            s = rng.choice(self.states) if self.states and rng.random() < 0.8 else c_void_p(77)
            return kind, raw.SetFMUstate(c, s)
        if kind == "freestate":
            s = rng.choice(self.states) if self.states else c_void_p()
            st = raw.FreeFMUstate(c, ctypes.byref(s))
            if s.value is None:
                self.states = [x for x in self.states if x.value is not None and x is not s]
            return kind, st
        if kind == "serialize":
            s = rng.choice(self.states) if self.states else c_void_p(99)
            size = c_size_t()
            st = raw.SerializedFMUstateSize(c, s, ctypes.byref(size))
            if st == 0:
                short = rng.random() < 0.2
                n = max(size.value - (1 if short else 0), 0)
                buf = ctypes.create_string_buffer(max(n, 1))
                st = raw.SerializeFMUstate(c, s, buf, n)
                if st == 0:
                    self.blobs.append(buf.raw[:n])
            return kind, st
        if kind == "deserialize":
            blob = rng.choice(self.blobs) if self.blobs and rng.random() < 0.6 else b""
            if blob and rng.random() < 0.5:  # damage it
                i = rng.randrange(len(blob))
                blob = blob[:i] + bytes([rng.randrange(256)]) + blob[i + 1 :]
            if rng.random() < 0.3:
                blob = bytes(rng.randrange(256) for _ in range(rng.choice([0, 8, 300, 2000])))
            s = c_void_p()
            st = raw.DeSerializeFMUstate(c, blob, len(blob), ctypes.byref(s))
            if st == 0 and s.value:
                self.states.append(s)
            return kind, st
        if kind == "status":
            which = rng.choice(["GetStatus", "GetRealStatus", "GetBooleanStatus"])
            out = {"GetRealStatus": c_double}.get(which, c_int)()
            return which, getattr(raw, which)(c, rng.randint(-1, 5), ctypes.byref(out))
        if kind == "cancel":
            return kind, raw.CancelStep(c)
        vr, n = self.refs()
        return kind, raw.GetDirectionalDerivative(c, vr, n, vr, n, None, None)

    def sequence(self) -> str | None:
        for _ in range(self.rng.randint(5, 40)):
            name, status = self.call()
            self.counts[name, status] += 1
            if status is not None and status not in (0, 1, 2, 3, 4):
                return f"{name} returned {status!r}"
        if self.rng.random() < 0.7:  # leave the rest to the next sequence otherwise
            for c in self.live:
                self.raw.FreeInstance(c)
            self.freed += self.live
            self.live, self.states = [], []
        return None


def main(argv: list[str]) -> int:
    seed, count, fmus = int(argv[0]), int(argv[1]), argv[2:]
    for fmu in fmus:
        raw = RawFMU(Path(fmu))
        rng = random.Random(f"{seed}:{Path(fmu).stem}")
        fuzzer = Fuzzer(raw, rng)
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
              f"{errors} fmi2Error", flush=True)  # fmt: skip
    print("done", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
