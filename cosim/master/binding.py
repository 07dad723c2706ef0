"""Our ctypes binding of an FMI 2.0 co-simulation binary (issue 48).

:class:`FMU2Binary` loads an FMU's shared library and makes the FMI 2.0 calls the master
makes, with the method names of fmpy's ``FMU2Slave`` that the rest of the master (and
:class:`~glider_cosim.master.fmi3.FMU3Adapter`, :class:`~glider_cosim.master.wasm.WasmAdapter`)
use: ``instantiate``, ``setupExperiment``, ``enterInitializationMode``,
``exitInitializationMode``, ``terminate``, ``reset``, ``fmi2FreeInstance``, get and set
Real, Integer, Boolean and String, ``doStep``, get, set and free the FMU state, and
``getDirectionalDerivative``. A call that returns more than fmi2Warning raises
:class:`~glider_cosim.master.errors.FMIStatusError` naming the call and the status.
:attr:`FMU2Binary.dll` is the loaded library, whose per-step functions
(``fmi2GetReal``, ..., ``fmi2DoStep``) carry their C prototypes, and
:attr:`FMU2Binary.component` the instance's address, for the exchange plan and the C fast
loop. fmpy, lxml and attrs are not imported: they cost a native run 30-40 ms of its start.

:func:`callbacks` builds the ``fmi2CallbackFunctions`` an instance gets: the master's
logger, and the C library's ``calloc`` and ``free`` themselves (no Python in between).
"""

from __future__ import annotations

import ctypes
import os
import pathlib
import sys
from collections.abc import Callable, Sequence
from typing import Any

from ..inputs.archives import FMI2_PLATFORM, LIBRARY_SUFFIX
from .errors import FMIStatusError

_P = ctypes.POINTER
_VR = _P(ctypes.c_uint)
_C, _I, _D, _S = ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_size_t
#: the C prototypes: name -> (restype, argtypes); fmi2Status, fmi2Boolean are C ints
PROTOTYPES: dict[str, tuple[Any, list[Any]]] = {
    "fmi2Instantiate": (_C, [ctypes.c_char_p, _I, ctypes.c_char_p, ctypes.c_char_p, _C, _I, _I]),
    "fmi2FreeInstance": (None, [_C]),
    "fmi2SetupExperiment": (_I, [_C, _I, _D, _D, _I, _D]),
    "fmi2EnterInitializationMode": (_I, [_C]),
    "fmi2ExitInitializationMode": (_I, [_C]),
    "fmi2Terminate": (_I, [_C]),
    "fmi2Reset": (_I, [_C]),
    "fmi2GetReal": (_I, [_C, _VR, _S, _P(_D)]),
    "fmi2GetInteger": (_I, [_C, _VR, _S, _P(_I)]),
    "fmi2GetBoolean": (_I, [_C, _VR, _S, _P(_I)]),
    "fmi2GetString": (_I, [_C, _VR, _S, _P(ctypes.c_char_p)]),
    "fmi2SetReal": (_I, [_C, _VR, _S, _P(_D)]),
    "fmi2SetInteger": (_I, [_C, _VR, _S, _P(_I)]),
    "fmi2SetBoolean": (_I, [_C, _VR, _S, _P(_I)]),
    "fmi2SetString": (_I, [_C, _VR, _S, _P(ctypes.c_char_p)]),
    "fmi2DoStep": (_I, [_C, _D, _D, _I]),
    "fmi2GetFMUstate": (_I, [_C, _P(_C)]),
    "fmi2SetFMUstate": (_I, [_C, _C]),
    "fmi2FreeFMUstate": (_I, [_C, _P(_C)]),
    "fmi2GetDirectionalDerivative": (_I, [_C, _VR, _S, _VR, _S, _P(_D), _P(_D)]),
}
#: what a co-simulation binary must export for the master (the rest on first use)
REQUIRED = tuple(n for n in PROTOTYPES if "FMUstate" not in n and "Directional" not in n)

#: ``void logger(env, instanceName, status, category, message, ...)``
LoggerType = ctypes.CFUNCTYPE(None, _C, ctypes.c_char_p, _I, ctypes.c_char_p, ctypes.c_char_p)
AllocateType = ctypes.CFUNCTYPE(_C, _S, _S)
FreeType = ctypes.CFUNCTYPE(None, _C)
StepFinishedType = ctypes.CFUNCTYPE(None, _C, _I)


class CallbackFunctions(ctypes.Structure):
    """``fmi2CallbackFunctions`` (FMI 2.0, section 2.1.5)."""

    _fields_ = [
        ("logger", LoggerType),
        ("allocateMemory", AllocateType),
        ("freeMemory", FreeType),
        ("stepFinished", StepFinishedType),
        ("componentEnvironment", _C),
    ]


_LIBC: list[Any] = []


def _c_memory() -> tuple[Any, Any]:
    """The C library's calloc and free as the callback types (their own addresses)."""
    if not _LIBC:
        libc = ctypes.cdll.msvcrt if sys.platform == "win32" else ctypes.CDLL(None)
        _LIBC.extend(
            (AllocateType(ctypes.cast(libc.calloc, _C).value),
             FreeType(ctypes.cast(libc.free, _C).value))
        )  # fmt: skip
    return _LIBC[0], _LIBC[1]


def callbacks(logger: Callable[[Any, bytes | None, int, bytes | None, bytes | None], None]) -> Any:
    """``fmi2CallbackFunctions`` with ``logger(env, instance_name, status, category,
    message)`` (the message unformatted: FMI's ``...`` arguments are not read), calloc and
    free; the caller keeps it alive as long as the instance."""
    cb = CallbackFunctions()
    cb.logger = LoggerType(logger)
    cb.allocateMemory, cb.freeMemory = _c_memory()
    return cb


class FMU2Binary:
    """An FMI 2.0 co-simulation FMU's binary and one instance of it.

    Parameters
    ----------
    guid : str
        The model description's ``guid``.
    unzipDirectory : str
        The folder the FMU is unpacked to (its ``resources`` are the resource location).
    modelIdentifier : str
        The co-simulation model identifier (the binary's file name).
    instanceName : str
        The instance's name.

    Raises
    ------
    OSError
        The binary is missing or cannot be loaded, or lacks an FMI function the master
        calls (named).
    """

    def __init__(self, guid: str, unzipDirectory: str, modelIdentifier: str, instanceName: str):
        self.guid, self.unzipDirectory, self.instanceName = guid, unzipDirectory, instanceName
        folder = os.path.abspath(os.path.join(unzipDirectory, "binaries", FMI2_PLATFORM))
        path = os.path.join(folder, modelIdentifier + LIBRARY_SUFFIX)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"no shared library {path}")
        cwd = os.getcwd()
        os.chdir(folder)  # as other hosts load it: some binaries find their own files so
        try:
            self.dll = ctypes.CDLL(path)
        finally:
            os.chdir(cwd)
        for name in REQUIRED:
            self._function(name)
        #: the instance's address (None until instantiated)
        self.component: int | None = None
        self.callbacks: Any = None

    def _function(self, name: str) -> Any:
        try:
            fn = getattr(self.dll, name)
        except AttributeError:
            raise OSError(f"{os.path.basename(self.dll._name)} has no function {name}") from None
        fn.restype, fn.argtypes = PROTOTYPES[name]
        return fn

    def _call(self, name: str, *args: Any) -> int:
        status = getattr(self.dll, name)(self.component, *args)
        if status > 1:
            raise FMIStatusError(name, status)
        return status

    # ------------------------------------------------------------- life cycle
    def instantiate(
        self, visible: bool = False, callbacks: Any = None, loggingOn: bool = False
    ) -> None:
        """fmi2Instantiate as co-simulation, ``resources`` as a ``file:`` URI."""
        self.callbacks = callbacks
        location = pathlib.Path(self.unzipDirectory, "resources").absolute().as_uri()
        self.component = self.dll.fmi2Instantiate(
            self.instanceName.encode("utf-8"), 1, self.guid.encode("utf-8"),
            location.encode("utf-8"), None if callbacks is None else ctypes.byref(callbacks),
            int(bool(visible)), int(bool(loggingOn)),
        )  # fmt: skip
        if self.component is None:
            raise FMIStatusError("fmi2Instantiate", 3)

    def setupExperiment(self, tolerance: float | None = None, startTime: float = 0.0,
                        stopTime: float | None = None) -> int:  # fmt: skip
        return self._call("fmi2SetupExperiment", tolerance is not None, tolerance or 0.0,
                          startTime, stopTime is not None, stopTime or 0.0)  # fmt: skip

    def enterInitializationMode(self) -> int:
        return self._call("fmi2EnterInitializationMode")

    def exitInitializationMode(self) -> int:
        return self._call("fmi2ExitInitializationMode")

    def terminate(self) -> int:
        return self._call("fmi2Terminate")

    def reset(self) -> int:
        return self._call("fmi2Reset")

    def fmi2FreeInstance(self, component: Any = None) -> None:
        """fmi2FreeInstance (the library stays loaded: see the master's ``_extracted``)."""
        self.dll.fmi2FreeInstance(self.component if component is None else component)

    freeInstance = fmi2FreeInstance

    def doStep(self, currentCommunicationPoint: float, communicationStepSize: float,
               noSetFMUStatePriorToCurrentPoint: bool = True) -> int:  # fmt: skip
        return self._call("fmi2DoStep", currentCommunicationPoint, communicationStepSize,
                          int(bool(noSetFMUStatePriorToCurrentPoint)))  # fmt: skip

    # ----------------------------------------------------------------- values
    def _get(self, kind: str, ctype: Any, vr: Sequence[int]) -> list:
        n = len(vr)
        values = (ctype * n)()
        self._call(f"fmi2Get{kind}", (ctypes.c_uint * n)(*vr), n, values)
        return list(values)

    def _set(self, kind: str, ctype: Any, vr: Sequence[int], values: Sequence[Any]) -> None:
        n = len(vr)
        self._call(f"fmi2Set{kind}", (ctypes.c_uint * n)(*vr), n, (ctype * n)(*values))

    def getReal(self, vr: Sequence[int]) -> list[float]:
        return self._get("Real", ctypes.c_double, vr)

    def getInteger(self, vr: Sequence[int]) -> list[int]:
        return self._get("Integer", ctypes.c_int, vr)

    def getBoolean(self, vr: Sequence[int]) -> list[int]:
        return self._get("Boolean", ctypes.c_int, vr)

    def getString(self, vr: Sequence[int]) -> list[bytes | None]:
        return self._get("String", ctypes.c_char_p, vr)

    def setReal(self, vr: Sequence[int], values: Sequence[float]) -> None:
        self._set("Real", ctypes.c_double, vr, values)

    def setInteger(self, vr: Sequence[int], values: Sequence[int]) -> None:
        self._set("Integer", ctypes.c_int, vr, values)

    def setBoolean(self, vr: Sequence[int], values: Sequence[Any]) -> None:
        self._set("Boolean", ctypes.c_int, vr, [int(bool(v)) for v in values])

    def setString(self, vr: Sequence[int], values: Sequence[str | None]) -> None:
        raw = [None if s is None else s.encode("utf-8") for s in values]
        self._set("String", ctypes.c_char_p, vr, raw)

    # ------------------------------------------------- FMU state, derivatives
    def getFMUstate(self) -> ctypes.c_void_p:
        state = ctypes.c_void_p()
        self._function("fmi2GetFMUstate")
        self._call("fmi2GetFMUstate", ctypes.byref(state))
        return state

    def setFMUstate(self, state: ctypes.c_void_p) -> None:
        self._function("fmi2SetFMUstate")
        self._call("fmi2SetFMUstate", state)

    def freeFMUstate(self, state: ctypes.c_void_p) -> None:
        self._function("fmi2FreeFMUstate")
        self._call("fmi2FreeFMUstate", ctypes.byref(state))

    getFMUState, setFMUState = getFMUstate, setFMUstate

    def getDirectionalDerivative(self, vUnknown_ref: Sequence[int], vKnown_ref: Sequence[int],
                                 dvKnown: Sequence[float]) -> list[float]:  # fmt: skip
        """d(unknowns) for the seed ``dvKnown`` of the knowns (FMI 2.0, section 2.1.9)."""
        nu, nk = len(vUnknown_ref), len(vKnown_ref)
        out = (ctypes.c_double * nu)()
        self._function("fmi2GetDirectionalDerivative")
        unknowns, knowns = (ctypes.c_uint * nu)(*vUnknown_ref), (ctypes.c_uint * nk)(*vKnown_ref)
        seed = (ctypes.c_double * nk)(*dvKnown)
        self._call("fmi2GetDirectionalDerivative", unknowns, nu, knowns, nk, seed, out)
        return list(out)
