"""Random FMI call sequences on FMUs, in one process: every call must return a status.

Usage: python tests/integration/fmi_fuzz.py SEED SEQUENCES FMU [FMU ...]

For each FMU, SEQUENCES sequences of 5-40 calls drawn at random: every FMI 2.0
co-simulation function, in any order, on live, freed and NULL instances, with valid and
unknown value references, nvr = 0, NULL arrays, non-finite times and steps, odd values,
FMU states real and forged, known and unknown log categories. Before each sequence the
line ``sequence FMU INDEX SEED`` is printed and flushed, so a crash names the sequence to
replay (the same SEED and FMU reproduce it). Exit 0 when every call returned a status
(0-4) or, for fmi2Instantiate, an instance or NULL; 1 with the offending call otherwise.
A crash shows up as a signal. What it shares with ``fmi3_fuzz.py`` is in
``fuzz_common.py``.
"""

from __future__ import annotations

import ctypes
import sys
from ctypes import c_char_p, c_double, c_int
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from fuzz_common import REALS, FuzzerBase, main  # noqa: E402
from raw_fmi import RawFMU  # noqa: E402


class Fuzzer(FuzzerBase):
    KINDS = [
        "instantiate", "free", "setup", "enter", "exit", "step", "step", "step",
        "terminate", "reset", "get", "get", "set", "set", "debug", "getstate", "setstate",
        "freestate", "serialize", "deserialize", "status", "cancel", "directional",
        "init", "init", "init", "step", "step", "step", "get", "reset",
    ]  # fmt: skip

    # ------------------------------------------------------------ arguments
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

    def boolean(self):
        return self.rng.randint(0, 1)

    def do_step(self, c, t, h):
        return self.raw.DoStep(c, t, h, self.boolean())

    # ------------------------------------------------------------ calls
    def call_setup(self, c):
        tol, start, stop = self.rng.choice(REALS), self.time(), self.time()
        return "setup", self.raw.SetupExperiment(c, self.boolean(), tol, start,
                                                 self.boolean(), stop)  # fmt: skip

    def call_enter(self, c):
        return "enter", self.raw.EnterInitializationMode(c)

    def typed(self):
        typ = self.rng.choice(["Real", "Integer", "Boolean", "String"])
        ctype = {"Real": c_double, "Integer": c_int, "Boolean": c_int, "String": c_char_p}[typ]
        return typ, ctype, *self.refs(typ)

    def call_get(self, c):
        typ, ctype, vr, n = self.typed()
        out = None if (n and self.rng.random() < 0.08) else (ctype * max(n, 1))()
        return f"get{typ}", getattr(self.raw, f"Get{typ}")(c, vr, n, out)

    def call_set(self, c):
        typ, ctype, vr, n = self.typed()
        return f"set{typ}", getattr(self.raw, f"Set{typ}")(c, vr, n, self.values(ctype, n))

    def call_status(self, c):
        which = self.rng.choice(["GetStatus", "GetRealStatus", "GetBooleanStatus"])
        out = {"GetRealStatus": c_double}.get(which, c_int)()
        return which, getattr(self.raw, which)(c, self.rng.randint(-1, 5), ctypes.byref(out))

    def call_cancel(self, c):
        return "cancel", self.raw.CancelStep(c)

    def call_directional(self, c):
        vr, n = self.refs()
        return "directional", self.raw.GetDirectionalDerivative(c, vr, n, vr, n, None, None)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:], RawFMU, Fuzzer))
