"""Raw ctypes access to an FMU's FMI 2.0 functions, for the runtime tests and the fuzz.

Unlike fmpy's ``FMU2Slave``, nothing here raises on a status or checks arguments: NULL
arrays, unknown value references and calls in any order go straight to the binary, and
every status and logged message is returned to the test.
"""

from __future__ import annotations

import ctypes
from ctypes import POINTER, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p
from dataclasses import dataclass
from pathlib import Path

from fmpy import calloc, free, read_model_description
from fmpy.fmi2 import (
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

from glider_cosim.master.instance import _extracted

STATUS = ("OK", "Warning", "Discard", "Error", "Fatal")
_VR = POINTER(c_uint)

# name -> (argtypes, restype) of the functions used here
_SIGNATURES = {
    "fmi2Instantiate": ([c_char_p, c_int, c_char_p, c_char_p, c_void_p, c_int, c_int], c_void_p),
    "fmi2FreeInstance": ([c_void_p], None),
    "fmi2SetDebugLogging": ([c_void_p, c_int, c_size_t, POINTER(c_char_p)], c_int),
    "fmi2SetupExperiment": ([c_void_p, c_int, c_double, c_double, c_int, c_double], c_int),
    "fmi2EnterInitializationMode": ([c_void_p], c_int),
    "fmi2ExitInitializationMode": ([c_void_p], c_int),
    "fmi2Terminate": ([c_void_p], c_int),
    "fmi2Reset": ([c_void_p], c_int),
    "fmi2GetReal": ([c_void_p, _VR, c_size_t, POINTER(c_double)], c_int),
    "fmi2GetInteger": ([c_void_p, _VR, c_size_t, POINTER(c_int)], c_int),
    "fmi2GetBoolean": ([c_void_p, _VR, c_size_t, POINTER(c_int)], c_int),
    "fmi2GetString": ([c_void_p, _VR, c_size_t, POINTER(c_char_p)], c_int),
    "fmi2SetReal": ([c_void_p, _VR, c_size_t, POINTER(c_double)], c_int),
    "fmi2SetInteger": ([c_void_p, _VR, c_size_t, POINTER(c_int)], c_int),
    "fmi2SetBoolean": ([c_void_p, _VR, c_size_t, POINTER(c_int)], c_int),
    "fmi2SetString": ([c_void_p, _VR, c_size_t, POINTER(c_char_p)], c_int),
    "fmi2GetFMUstate": ([c_void_p, POINTER(c_void_p)], c_int),
    "fmi2SetFMUstate": ([c_void_p, c_void_p], c_int),
    "fmi2FreeFMUstate": ([c_void_p, POINTER(c_void_p)], c_int),
    "fmi2SerializedFMUstateSize": ([c_void_p, c_void_p, POINTER(c_size_t)], c_int),
    "fmi2SerializeFMUstate": ([c_void_p, c_void_p, c_char_p, c_size_t], c_int),
    "fmi2DeSerializeFMUstate": ([c_void_p, c_char_p, c_size_t, POINTER(c_void_p)], c_int),
    "fmi2DoStep": ([c_void_p, c_double, c_double, c_int], c_int),
    "fmi2CancelStep": ([c_void_p], c_int),
    "fmi2GetStatus": ([c_void_p, c_int, POINTER(c_int)], c_int),
    "fmi2GetRealStatus": ([c_void_p, c_int, POINTER(c_double)], c_int),
    "fmi2GetBooleanStatus": ([c_void_p, c_int, POINTER(c_int)], c_int),
    "fmi2GetDirectionalDerivative": (
        [c_void_p, _VR, c_size_t, _VR, c_size_t, POINTER(c_double), POINTER(c_double)],
        c_int,
    ),
}


@dataclass
class Message:
    instance: str
    status: int
    category: str
    text: str


class RawFMU:
    """An FMU's binary loaded with ctypes; ``messages`` collects what it logs."""

    def __init__(self, fmu: Path):
        self.fmu = Path(fmu)
        self.md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.dir = Path(_extracted(self.fmu))
        #: the native flavor (C model), not a Python slave
        self.native = not (self.dir / "resources" / "slavemodule.txt").is_file()
        ident = self.md.coSimulation.modelIdentifier
        self.dll = ctypes.CDLL(str(self.dir / "binaries" / "linux64" / f"{ident}.so"))
        for name, (args, res) in _SIGNATURES.items():
            f = getattr(self.dll, name)
            f.argtypes, f.restype = args, res
        self.messages: list[Message] = []

        def log(env, instance, status, category, message):
            text = (message or b"").decode("utf-8", "replace").replace("%%", "%")
            self.messages.append(
                Message((instance or b"").decode(), status, (category or b"").decode(), text)
            )

        self._logger = fmi2CallbackLoggerTYPE(log)
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = self._logger
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)

    def instantiate(self, name: str = "x", logging: bool = False, resources: str | None = None):
        uri = resources if resources is not None else (self.dir / "resources").as_uri()
        return self.dll.fmi2Instantiate(name.encode(), 1, self.md.guid.encode(), uri.encode(),
                                        ctypes.byref(self.callbacks), 0, int(logging))  # fmt: skip

    def __getattr__(self, name: str):
        """``raw.DoStep(c, ...)`` calls ``fmi2DoStep``."""
        return getattr(self.dll, f"fmi2{name}")

    def refs(self, *names: str):
        return (c_uint * len(names))(*(self.vr[n] for n in names))

    def get_real(self, c, *names: str) -> tuple[int, list[float]]:
        out = (c_double * len(names))()
        st = self.dll.fmi2GetReal(c, self.refs(*names), len(names), out)
        return st, list(out)

    def set_real(self, c, **values: float) -> int:
        vals = (c_double * len(values))(*values.values())
        return self.dll.fmi2SetReal(c, self.refs(*values), len(values), vals)

    def set_integer(self, c, **values: int) -> int:
        vals = (c_int * len(values))(*values.values())
        return self.dll.fmi2SetInteger(c, self.refs(*values), len(values), vals)

    def initialize(self, c, **params: float) -> int:
        """SetupExperiment at 0, set Reals, enter and exit initialisation; worst status."""
        st = [self.dll.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0)]
        if params:
            st.append(self.set_real(c, **params))
        st.append(self.dll.fmi2EnterInitializationMode(c))
        st.append(self.dll.fmi2ExitInitializationMode(c))
        return max(st)

    def errors(self) -> list[str]:
        return [m.text for m in self.messages if m.status >= 3]


LOOP_LINKS = (  # Jacobi exchange of the default loop (observer feedback)
    ("plant", "theta_meas", "observer", "theta_meas"),
    ("controller", "delta_cmd", "observer", "delta_cmd"),
    ("observer", "V_hat", "controller", "V_hat"),
    ("observer", "theta_g_hat", "controller", "theta_g_hat"),
    ("controller", "delta_cmd", "plant", "delta_cmd"),
)


class Loop:
    """The three glider FMUs as a closed loop on raw calls (Jacobi coupling, 50 Hz)."""

    def __init__(self, raws: dict[str, RawFMU], name: str = "x"):
        self.raws = raws
        self.name = name
        self.c: dict[str, int] = {}
        self.k = 0
        self.h = 0.02

    def instantiate(self) -> None:
        for inst, raw in self.raws.items():
            self.c[inst] = raw.instantiate(f"{self.name}-{inst}")
            assert self.c[inst], raw.errors()

    def initialize(self, params: dict[str, dict[str, float]]) -> None:
        for inst, raw in self.raws.items():
            reals = {k: v for k, v in params.get(inst, {}).items() if raw.types[k] == "Real"}
            ints = {k: v for k, v in params.get(inst, {}).items() if raw.types[k] == "Integer"}
            c = self.c[inst]
            assert raw.SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == 0
            assert not reals or raw.set_real(c, **reals) == 0
            assert not ints or raw.set_integer(c, **ints) == 0
            assert raw.EnterInitializationMode(c) == 0
            assert raw.ExitInitializationMode(c) == 0, raw.errors()

    def outputs(self) -> list[float]:
        values = []
        for inst, raw in self.raws.items():
            names = [v.name for v in raw.md.modelVariables if v.causality == "output"]
            names = [n for n in names if raw.types[n] == "Real"]
            st, vals = raw.get_real(self.c[inst], *names)
            assert st == 0
            values += vals
        return values

    def step(self, n: int) -> list[list[float]]:
        rows = []
        for _ in range(n):
            values = []
            for src, out, _dst, _inp in LOOP_LINKS:
                st, (v,) = self.raws[src].get_real(self.c[src], out)
                assert st == 0
                values.append(v)
            for (_src, _out, dst, inp), v in zip(LOOP_LINKS, values):
                assert self.raws[dst].set_real(self.c[dst], **{inp: v}) == 0
            t = self.k * self.h
            for inst, raw in self.raws.items():
                assert raw.DoStep(self.c[inst], t, self.h, 1) == 0, raw.errors()
            self.k += 1
            rows.append(self.outputs())
        return rows

    def free(self) -> None:
        for inst, raw in self.raws.items():
            raw.FreeInstance(self.c[inst])
        self.c = {}
