"""What the FMI 2.0 and FMI 3.0 call-sequence fuzzers share (``fmi_fuzz.py``,
``fmi3_fuzz.py``): the argument pools, the calls both standards have, the sequence loop
and the command line.

A fuzzer draws a kind from ``KINDS`` and an instance (live, freed or NULL), then calls
its method ``call_<kind>(c)``, which returns the name counted and the status (None for
calls without one). The subclass names the standard's spellings (``STATE``,
``DESERIALIZE``, ``ERROR``), how its booleans are drawn and how it steps.
"""

from __future__ import annotations

import collections
import ctypes
import math
import random
from ctypes import c_char_p, c_size_t, c_uint, c_void_p
from pathlib import Path

CATEGORIES = [b"logAll", b"logStatusError", b"logStatusWarning", b"logFmiCalls", b"nope", None]
REALS = [0.0, 1.0, -1.0, 0.02, 1e308, -1e308, math.inf, -math.inf, math.nan, 5e-324, 1e-3]


class FuzzerBase:
    #: the kinds of call, drawn with these weights (one entry, one chance)
    KINDS: list[str] = []
    #: the default type of ``refs`` (the FMI 2 Real, the FMI 3 Float64)
    REAL = "Real"
    #: how far past the number of variables odd value references go
    VR_SLACK = 0
    #: the spelling of the FMU state functions: ``Get{STATE}``, ``SerializedFMUStateSize``
    STATE = "FMUstate"
    DESERIALIZE = "DeSerializeFMUstate"
    #: the name of the error status in the summary line
    ERROR = "fmi2Error"
    #: what no message of this front end may hold: the other FMI version's function
    #: names (an FMI 3 instance's messages name fmi3 functions alone), or None
    FOREIGN: bytes | None = None

    def __init__(self, raw, rng: random.Random):
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

    def refs(self, typ: str | None = None):
        n = self.rng.choice([0, 1, 1, 2, 3, 5])
        if n and self.rng.random() < 0.05:
            return None, n
        pool = self.by_type.get(typ or self.REAL) or [0]
        if self.rng.random() < 0.2:  # anything, of any type or none
            top = self.nvars + self.VR_SLACK
            pool = [self.rng.randrange(top), top, 10**6, 2**32 - 1]
        return (c_uint * max(n, 1))(*(self.rng.choice(pool) for _ in range(max(n, 1)))), n

    def time(self):
        return self.rng.choice([0.0, 0.02, 0.04, -1.0, math.nan, math.inf, 1e9])

    def boolean(self):
        """A boolean argument, as the standard's type takes it."""
        raise NotImplementedError

    def do_step(self, c, t: float, h: float) -> int:
        """The standard's doStep at ``t`` with step ``h``, the other arguments drawn."""
        raise NotImplementedError

    # ------------------------------------------------------------ calls
    def call(self) -> tuple[str, object]:
        kind = self.rng.choice(self.KINDS)
        return getattr(self, f"call_{kind}")(self.comp())

    def call_instantiate(self, c):
        h = self.raw.instantiate(f"f{len(self.live)}", logging=self.rng.random() < 0.3)
        if h:
            self.live.append(h)
        return "instantiate", None

    def call_free(self, c):
        if c in self.live:
            self.live.remove(c)
            self.freed.append(c)
        self.raw.FreeInstance(c)
        return "free", None

    def call_init(self, c):  # the proper sequence, to reach the states after it
        if c is None or c in self.freed:
            c = self.raw.instantiate(f"f{len(self.live)}", logging=self.rng.random() < 0.3)
            if not c:
                return "init", None
            self.live.append(c)
        self.t[c] = 0.0
        return "init", self.raw.initialize(c)

    def call_exit(self, c):
        return "exit", self.raw.ExitInitializationMode(c)

    def call_step(self, c):
        rng = self.rng
        h = rng.choice([0.02, 0.02, 0.02, 0.02, 0.0, -0.02, math.nan, math.inf, 1e-9, 10.0])
        t = self.t.get(c, 0.0) if rng.random() < 0.8 else self.time()
        st = self.do_step(c, t, h)
        if st == 0:
            self.t[c] = t + h
        return "step", st

    def call_terminate(self, c):
        return "terminate", self.raw.Terminate(c)

    def call_reset(self, c):
        return "reset", self.raw.Reset(c)

    def call_debug(self, c):
        rng = self.rng
        n = rng.randint(0, 3)
        cats = None if (n and rng.random() < 0.1) else (c_char_p * max(n, 1))(
            *(rng.choice(CATEGORIES) for _ in range(max(n, 1))))  # fmt: skip
        return "debug", self.raw.SetDebugLogging(c, self.boolean(), n, cats)

    def call_getstate(self, c):
        rng = self.rng
        s = c_void_p() if rng.random() < 0.7 or not self.states else rng.choice(self.states)
        st = getattr(self.raw, f"Get{self.STATE}")(c, ctypes.byref(s))
        if st == 0 and s.value and s not in self.states:
            self.states.append(s)
        return "getstate", st

    def call_setstate(self, c):
        rng = self.rng
        s = rng.choice(self.states) if self.states and rng.random() < 0.8 else c_void_p(77)
        return "setstate", getattr(self.raw, f"Set{self.STATE}")(c, s)

    def call_freestate(self, c):
        s = self.rng.choice(self.states) if self.states else c_void_p()
        st = getattr(self.raw, f"Free{self.STATE}")(c, ctypes.byref(s))
        if s.value is None:
            self.states = [x for x in self.states if x.value is not None and x is not s]
        return "freestate", st

    def call_serialize(self, c):
        raw, rng = self.raw, self.rng
        s = rng.choice(self.states) if self.states else c_void_p(99)
        size = c_size_t()
        st = getattr(raw, f"Serialized{self.STATE}Size")(c, s, ctypes.byref(size))
        if st == 0:
            n = max(size.value - (1 if rng.random() < 0.2 else 0), 0)  # sometimes one short
            buf = ctypes.create_string_buffer(max(n, 1))
            st = getattr(raw, f"Serialize{self.STATE}")(c, s, buf, n)
            if st == 0:
                self.blobs.append(buf.raw[:n])
        return "serialize", st

    def call_deserialize(self, c):
        rng = self.rng
        blob = rng.choice(self.blobs) if self.blobs and rng.random() < 0.6 else b""
        if blob and rng.random() < 0.5:  # damage it
            i = rng.randrange(len(blob))
            blob = blob[:i] + bytes([rng.randrange(256)]) + blob[i + 1 :]
        if rng.random() < 0.3:
            blob = bytes(rng.randrange(256) for _ in range(rng.choice([0, 8, 300, 2000])))
        s = c_void_p()
        st = getattr(self.raw, self.DESERIALIZE)(c, blob, len(blob), ctypes.byref(s))
        if st == 0 and s.value:
            self.states.append(s)
        return "deserialize", st

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


def main(argv: list[str], raw_class, fuzzer_class, seed_tag: str = "") -> int:
    """``SEED SEQUENCES FMU [FMU ...]``: the sequences of each FMU, drawn from the seed
    ``SEED:{seed_tag}STEM``; 0 when every call returned a status, 1 otherwise."""
    seed, count, fmus = int(argv[0]), int(argv[1]), argv[2:]
    for fmu in fmus:
        raw = raw_class(Path(fmu))
        rng = random.Random(f"{seed}:{seed_tag}{Path(fmu).stem}")
        fuzzer = fuzzer_class(raw, rng)
        for i in range(count):
            print(f"sequence {Path(fmu).stem} {i} {seed}", flush=True)
            problem = fuzzer.sequence()
            foreign = fuzzer_class.FOREIGN
            if not problem and foreign:
                bad = [m for _, m in raw.messages if foreign in m]
                problem = (
                    f"a message names another FMI version's function: {bad[0]!r}" if bad else None
                )
            if problem:
                print(f"FAILED {Path(fmu).stem} sequence {i} seed {seed}: {problem}", flush=True)
                return 1
            raw.messages.clear()
        for c in fuzzer.live:
            raw.FreeInstance(c)
        ok_steps = fuzzer.counts["step", 0]
        errors = sum(n for (_, st), n in fuzzer.counts.items() if st == 3)
        print(f"{Path(fmu).stem}: {sum(fuzzer.counts.values())} calls, {ok_steps} steps OK, "
              f"{errors} {fuzzer_class.ERROR}", flush=True)  # fmt: skip
    print("done", flush=True)
    return 0
