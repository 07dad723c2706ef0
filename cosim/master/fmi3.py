"""An FMI 3.0 co-simulation instance behind the FMI 2.0 calls the master makes.

The master (:mod:`glider_cosim.master.cosimulation`) drives its instances with the
methods of fmpy's ``FMU2Slave`` (instantiate, setupExperiment, enter/exit initialisation,
terminate, reset, free, set/get Real/Integer/Boolean, doStep) and, in its C fast loop,
with the FMI 2.0 functions themselves (``fmi2GetReal(c, vr, n, values)``,
``fmi2DoStep(c, t, h, noSetPrior)``). :class:`FMU3Adapter` wraps fmpy's ``FMU3Slave`` in
the same methods: setupExperiment stores the start time, which fmi3EnterInitializationMode
receives; Float64, Int32 and Boolean stand for Real, Integer and Boolean; a doStep that
sets ``terminateSimulation`` raises the Discard an FMI 2.0 FMU returns for a stall. Its
:attr:`~FMU3Adapter.component` is the address of a small C structure (the fmi3 instance
and its FMU's fmi3 functions) that the shims of ``fastloop.c`` take in place of an FMI 2.0
component: ``glider_shim_get_float64`` calls fmi3GetFloat64 with ``nValues = n``,
``glider_shim_do_step`` calls fmi3DoStep and returns fmi3Discard when the FMU sets
``terminateSimulation`` (a stall), which the master treats as the clean stop an FMI 2.0
fmi2Discard is. The C fast loop and the block runs therefore serve FMI 3.0 instances
unchanged, with one more C call per FMI call. Without a C compiler (no shims), the fast
loop is not used, and the master steps the instance through fmpy's methods.
"""

from __future__ import annotations

import ctypes
from typing import Any

from ..fmus.fmi3_description import FMI3_TYPES
from .errors import FMIStatusError
from .fastloop import SHIMS, shim_library

#: FMI 3 types the master treats as the FMI 2 ones
TYPE_AS_FMI2 = {v3: v2 for v2, v3 in FMI3_TYPES.items()}
#: FMI 2 call names (as the master writes them) -> the FMI 3 call made
CALL_NAMES = {
    "fmi2Instantiate": "fmi3InstantiateCoSimulation",
    "fmi2SetupExperiment": "fmi3EnterInitializationMode",
    "fmi2GetReal": "fmi3GetFloat64",
    "fmi2SetReal": "fmi3SetFloat64",
    "fmi2GetInteger": "fmi3GetInt32",
    "fmi2SetInteger": "fmi3SetInt32",
    "fmi2GetBoolean": "fmi3GetBoolean",
    "fmi2SetBoolean": "fmi3SetBoolean",
}


def fmi3_call_name(call: str) -> str:
    """``"fmi2SetReal(K_c)"`` -> ``"fmi3SetFloat64(K_c)"``; ``fmi2X`` -> ``fmi3X``."""
    base, paren, rest = call.partition("(")
    base = CALL_NAMES.get(base, base.replace("fmi2", "fmi3", 1))
    return base + paren + rest


class _Adapter(ctypes.Structure):
    """``Fmi3Adapter`` of ``fastloop.c``."""

    _fields_ = [
        ("instance", ctypes.c_void_p),
        ("get_float64", ctypes.c_void_p),
        ("set_float64", ctypes.c_void_p),
        ("get_int32", ctypes.c_void_p),
        ("set_int32", ctypes.c_void_p),
        ("get_boolean", ctypes.c_void_p),
        ("set_boolean", ctypes.c_void_p),
        ("do_step", ctypes.c_void_p),
    ]


_FIELDS = {
    "get_float64": "fmi3GetFloat64",
    "set_float64": "fmi3SetFloat64",
    "get_int32": "fmi3GetInt32",
    "set_int32": "fmi3SetInt32",
    "get_boolean": "fmi3GetBoolean",
    "set_boolean": "fmi3SetBoolean",
    "do_step": "fmi3DoStep",
}


class ShimCalls:
    """The per-step calls of an FMI 3 instance under their FMI 2 names (what
    :meth:`glider_cosim.master.instance.Instance.call_dll` returns for it)."""

    def __init__(self, functions: dict[str, Any], holds_gil: bool):
        for name, fn in functions.items():
            setattr(self, name, fn)
        #: the functions are called with the GIL held (like a ``ctypes.PyDLL``)
        self.holds_gil = holds_gil


class FMU3Adapter:
    """fmpy's ``FMU3Slave`` with the ``FMU2Slave`` methods the master calls.

    Parameters are those of ``FMU3Slave`` (``guid`` is the instantiation token).
    """

    def __init__(self, **kwargs: Any):
        from fmpy.fmi3 import FMU3Slave

        self.slave = FMU3Slave(**kwargs)
        self.dll = self.slave.dll
        self._adapter = _Adapter()
        raw = ctypes.CDLL(self.dll._name)  # plain function pointers, no argtypes
        for field, fn_name in _FIELDS.items():
            setattr(self._adapter, field, ctypes.cast(getattr(raw, fn_name), ctypes.c_void_p))
        self._experiment: tuple[float | None, float, float | None] = (None, 0.0, None)
        self._log: Any = None

    @property
    def component(self) -> int:
        """What the per-step calls take as their component: the adapter's address."""
        return ctypes.addressof(self._adapter)

    def calls(self, holds_gil: bool) -> ShimCalls | None:
        """The per-step calls for the C fast loop (the C shims), or None without a C
        compiler."""
        lib = shim_library(holds_gil)
        if lib is None:
            return None
        return ShimCalls({k: getattr(lib, v) for k, v in SHIMS.items()}, holds_gil)

    # ---------------------------------------------------------- FMU2Slave's methods
    def instantiate(self, log_message: Any = None, loggingOn: bool = False) -> None:
        """fmi3InstantiateCoSimulation with ``log_message(env, status, category,
        message)`` as the log callback; no event mode, no early return."""
        self.slave.instantiate(loggingOn=loggingOn, logMessage=log_message)
        self._log = self.slave.logMessage
        self._adapter.instance = self.slave.component

    def setupExperiment(self, tolerance=None, startTime=0.0, stopTime=None) -> None:
        """Stored: FMI 3 takes the experiment in fmi3EnterInitializationMode."""
        self._experiment = (tolerance, startTime, stopTime)

    def enterInitializationMode(self) -> None:
        tolerance, start, stop = self._experiment
        self.slave.enterInitializationMode(tolerance=tolerance, startTime=start, stopTime=stop)

    def exitInitializationMode(self) -> None:
        self.slave.exitInitializationMode()

    def terminate(self) -> int:
        return self.slave.terminate()

    def reset(self) -> int:
        return self.slave.reset()

    def fmi2FreeInstance(self, component: Any = None) -> None:
        """fmi3FreeInstance (the component argument is ignored: it is the adapter)."""
        self.slave.fmi3FreeInstance(self.slave.component)
        self._adapter.instance = None

    def setReal(self, vr, values) -> None:
        self.slave.setFloat64(vr, values)

    def setInteger(self, vr, values) -> None:
        self.slave.setInt32(vr, values)

    def setBoolean(self, vr, values) -> None:
        self.slave.setBoolean(vr, values)

    def doStep(self, currentCommunicationPoint, communicationStepSize,
               noSetFMUStatePriorToCurrentPoint=True) -> None:  # fmt: skip
        """fmi3DoStep; :class:`~glider_cosim.master.errors.FMIStatusError` with fmi3Discard
        when the FMU sets ``terminateSimulation`` (a stall: the master's clean stop)."""
        _, terminate, _, _ = self.slave.doStep(
            currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint
        )
        if terminate:
            raise FMIStatusError("fmi3DoStep", 2)

    def getReal(self, vr) -> list[float]:
        return self.slave.getFloat64(vr)

    def getInteger(self, vr) -> list[int]:
        return self.slave.getInt32(vr)

    def getBoolean(self, vr) -> list[bool]:
        return self.slave.getBoolean(vr)

    # FMI 3 only, for hosts of ours that need it
    def getFMUState(self) -> Any:
        return self.slave.getFMUState()

    def setFMUState(self, state: Any) -> None:
        self.slave.setFMUState(state)


__all__ = ["FMU3Adapter", "ShimCalls", "TYPE_AS_FMI2", "fmi3_call_name"]
