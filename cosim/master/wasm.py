"""Our FMUs' WebAssembly components (FMI-LS-WASM) under the master, through wasmtime.

``glider-cosim run --flavor wasm`` runs the native FMI 3.0 FMUs' components
(``binaries/wasm32-wasip2/<id>.wasm``, :mod:`glider_cosim.fmus.wasm`) instead of their
shared libraries: :class:`WasmAdapter` has the methods of fmpy's ``FMU2Slave`` that the
master calls on an FMU (as :class:`~glider_cosim.master.fmi3.FMU3Adapter` has for an FMI
3.0 library), each one call of the component's ``co-simulation-instance`` resource
through wasmtime's component API (``wasmtime.component``); no C fast loop: the master
steps it through these methods. The
component gets one import, ``fmi:fmi3/callbacks@3.0.0#log-message``, which passes each
message to the master's FMI 3.0 logger: the same statuses and texts as the native FMUs.

A ``result<T, status>`` is T (OK or Warning) or the status' name; do-step's err(discard)
and ok with ``terminate-simulation`` both are the clean stop (fmi2Discard) the master knows.
"""

from __future__ import annotations

import atexit
import contextlib
import contextvars
import ctypes
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..fmus.wasm import WASM_PLATFORM
from .errors import FMIStatusError

#: WIT status names -> FMI's numbers
STATUS = {"ok": 0, "warning": 1, "discard": 2, "error": 3, "fatal": 4}
CO_SIMULATION = "fmi:fmi3/co-simulation@3.0.0"
COMMON = "fmi:fmi3/common@3.0.0"
CALLBACKS = "fmi:fmi3/callbacks@3.0.0"
RESOURCE = "co-simulation-instance"

_RUN_WASM: contextvars.ContextVar[bool] = contextvars.ContextVar("glider_run_wasm", default=False)
_ENGINE: Any = None
_COMPONENTS: dict[tuple[str, int, int], Any] = {}
_LOCK = threading.Lock()


@atexit.register
def _release() -> None:
    """Drop the compiled components before wasmtime's bindings go at interpreter exit."""
    global _ENGINE
    _COMPONENTS.clear()
    _ENGINE = None


class WasmError(RuntimeError):
    """A component cannot be loaded or run (missing, not a component, a trap)."""


@contextlib.contextmanager
def components(on: bool = True) -> Iterator[None]:
    """Within the block (in this thread), the master runs FMI 3.0 FMUs' WebAssembly
    components instead of their native binaries (``run --flavor wasm``)."""
    token = _RUN_WASM.set(on)
    try:
        yield
    finally:
        _RUN_WASM.reset(token)


def use_components(on: bool) -> None:
    """From now on (in this thread), the master runs FMI 3.0 FMUs' components if ``on``
    (the command line's ``--flavor wasm``, set for each command)."""
    _RUN_WASM.set(on)


def wanted() -> bool:
    """True inside :func:`components`."""
    return _RUN_WASM.get()


def component_path(unzipdir: str | Path, model_identifier: str) -> Path:
    """Where FMI-LS-WASM puts an FMU's component."""
    return Path(unzipdir) / "binaries" / WASM_PLATFORM / f"{model_identifier}.wasm"


def load_component(path: Path) -> tuple[Any, Any]:
    """(engine, compiled component) for ``path``, compiled once per process and file
    version (wasmtime compiles to machine code: a fraction of a second)."""
    global _ENGINE
    import wasmtime
    import wasmtime.component as wc

    st = path.stat()
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    with _LOCK:
        if _ENGINE is None:
            _ENGINE = wasmtime.Engine()
        if key not in _COMPONENTS:
            try:
                _COMPONENTS[key] = wc.Component.from_file(_ENGINE, str(path))
            except wasmtime.WasmtimeError as err:
                first = str(err).strip().splitlines()[0] if str(err).strip() else "invalid"
                raise WasmError(f"{path.name} is not a WebAssembly component: {first}") from None
        return _ENGINE, _COMPONENTS[key]


class _Call:
    """A component function with its parameter and result types looked up once (wasmtime's
    ``Func.__call__`` reflects them at every call), called and post-returned."""

    def __init__(self, store: Any, func: Any):
        fty = func.type(store)
        self.store, self.func = store, func
        self.params = [ty for _, ty in fty.params]
        self.result = fty.result

    def __call__(self, *args: Any) -> Any:
        from wasmtime import _ffi as ffi
        from wasmtime.component._enter import enter_wasm

        store, n = self.store, 0
        params = (ffi.wasmtime_component_val_t * len(args))()
        try:
            for ty, val in zip(self.params, args):
                ty.convert_to_c(store, val, ctypes.pointer(params[n]))
                n += 1
            space = ffi.wasmtime_component_val_t() if self.result is not None else None
            func = self.func._func

            def run() -> Any:
                return ffi.wasmtime_component_func_call(
                    ctypes.byref(func), store._context(), params, n,
                    ctypes.byref(space) if space is not None else None,
                    1 if space is not None else 0,
                )  # fmt: skip

            enter_wasm(run)
            out = None if space is None else self.result.convert_from_c(space)
        finally:
            for i in range(n):
                ffi.wasmtime_component_val_delete(ctypes.byref(params[i]))
        self.func.post_return(store)
        return out


def fmi3_name(wit: str) -> str:
    """The FMI 3.0 call of a WIT function: ``"do-step"`` -> ``"fmi3DoStep"``."""
    words = wit.rpartition(".")[2].split("-")
    name = "".join(w.capitalize() for w in words)
    return "fmi3" + name.replace("Uint", "UInt").replace("Fmu", "FMU")


def _wasmtime_error() -> type[Exception]:
    import wasmtime

    return wasmtime.WasmtimeError


def _status(result: Any) -> int:
    return STATUS[result] if isinstance(result, str) else 0


class WasmAdapter:
    """An FMI 3.0 FMU's component with the ``FMU2Slave`` methods the master calls (the
    arguments of fmpy's ``FMU3Slave``: ``guid`` is the instantiation token)."""

    def __init__(self, guid: str, unzipDirectory: str, modelIdentifier: str, instanceName: str,
                 **_: Any):  # fmt: skip
        import wasmtime
        import wasmtime.component as wc

        path = component_path(unzipDirectory, modelIdentifier)
        if not path.is_file():
            raise WasmError(
                f"no WebAssembly component binaries/{WASM_PLATFORM}/{modelIdentifier}.wasm "
                "(build the native FMI 3 FMUs with zig and wasm-tools installed)"
            )
        engine, component = load_component(path)
        self.guid, self.name, self.unzipdir = guid, instanceName, str(unzipDirectory)
        self.dll = None  # no shared library: the master calls the methods below
        self._log: Any = None
        self._resource: Any = None
        self._experiment: tuple[float | None, float, float | None] = (None, 0.0, None)
        linker = wc.Linker(engine)
        with linker.root() as root:
            with root.add_instance(CALLBACKS) as cb:
                cb.add_func("log-message", self._log_message)
        self.store = wasmtime.Store(engine)
        try:
            self._instance = linker.instantiate(self.store, component)
        except wasmtime.WasmtimeError as err:
            raise WasmError(f"{path.name}: {str(err).strip().splitlines()[0]}") from None
        store, inst = self.store, self._instance
        iface = inst.get_export_index(store, CO_SIMULATION)
        common = inst.get_export_index(store, COMMON)
        if iface is None or common is None:
            raise WasmError(f"{path.name} exports no {CO_SIMULATION} (not an FMI-LS-WASM FMU)")
        self._iface = iface
        #: the component trapped: every later call is fatal, none is made
        self.trapped = False
        self._calls: dict[str, _Call] = {}
        self._version = _Call(store, inst.get_func(store, inst.get_export_index(
            store, "get-version", common)))  # fmt: skip

    # ---------------------------------------------------------------- calls
    def call(self, name: str, *args: Any) -> Any:
        """The resource's function ``name`` (``"do-step"``; ``"[static]..."`` as is) with
        this adapter's instance first for a method."""
        return self.method(self._resource, name, *args)

    def method(self, resource: Any, name: str, *args: Any) -> Any:
        """The resource's function ``name`` on ``resource`` (a static one: not passed)."""
        fn = self._calls.get(name)
        if fn is None:
            full = name if name.startswith("[") else f"[method]{RESOURCE}.{name}"
            idx = self._instance.get_export_index(self.store, full, self._iface)
            if idx is None:
                raise WasmError(f"the component exports no {full}")
            fn = self._calls[name] = _Call(self.store, self._instance.get_func(self.store, idx))
        if self.trapped:
            return "fatal"
        try:
            return fn(*args) if name.startswith("[") else fn(resource, *args)
        except _wasmtime_error() as err:  # a trap: the instance cannot be entered again
            self.trapped = True
            first = (str(err).strip().splitlines() or ["trap"])[0]
            if self._log is not None:
                text = f"{self.name}: {fmi3_name(name)}: the component trapped ({first})"
                self._log(None, 4, b"logStatusFatal", text.encode())
            return "fatal"

    def _log_message(self, store: Any, name: str, status: str, category: str, message: str):
        if self._log is not None:
            self._log(None, STATUS.get(status, 3), category.encode(), message.encode())

    def _check(self, call: str, result: Any) -> Any:
        st = _status(result)
        if st > 1:
            raise FMIStatusError(call, st)
        return result

    @property
    def component(self) -> int:
        """Not a pointer: the methods know their instance."""
        return 0

    def get_version(self) -> str:
        """``common.get-version``"""
        return self._version()

    # ---------------------------------------------------------- FMU2Slave's methods
    def instantiate(self, log_message: Any = None, loggingOn: bool = False) -> None:
        """``instantiate-co-simulation`` with ``log_message(env, status, category,
        message)`` receiving the component's messages; no event mode, no early return."""
        self._log = log_message
        res = self.call(f"[static]{RESOURCE}.instantiate-co-simulation", self.name, self.guid,
                        "", False, bool(loggingOn), False, False, [])  # fmt: skip
        if res is None or isinstance(res, str):
            raise FMIStatusError("fmi3InstantiateCoSimulation", 4 if res else 3)
        self._resource = res

    def setupExperiment(self, tolerance=None, startTime=0.0, stopTime=None) -> None:
        """Stored: FMI 3 takes the experiment in enter-initialization-mode."""
        self._experiment = (tolerance, startTime, stopTime)

    def enterInitializationMode(self) -> None:
        tolerance, start, stop = self._experiment
        status = self.call("enter-initialization-mode", tolerance, float(start), stop)
        self._check("fmi3EnterInitializationMode", status)

    def exitInitializationMode(self) -> None:
        self._check("fmi3ExitInitializationMode", self.call("exit-initialization-mode"))

    def terminate(self) -> int:
        return _status(self._check("fmi3Terminate", self.call("terminate")))

    def reset(self) -> int:
        return _status(self._check("fmi3Reset", self.call("reset")))

    def fmi2FreeInstance(self, component: Any = None) -> None:
        """Drop the resource (fmi3FreeInstance)."""
        if self._resource is not None:
            res, self._resource = self._resource, None
            if not self.trapped:
                with contextlib.suppress(_wasmtime_error()):
                    res.drop(self.store)

    def _set(self, what: str, call: str, vr: Any, values: list) -> None:
        self._check(call, self.call(what, [int(v) for v in vr], values))

    def _get(self, what: str, call: str, vr: Any) -> list:
        return self._check(call, self.call(what, [int(v) for v in vr]))

    def setReal(self, vr, values) -> None:
        self._set("set-float64", "fmi3SetFloat64", vr, [float(v) for v in values])

    def setInteger(self, vr, values) -> None:
        self._set("set-int32", "fmi3SetInt32", vr, [int(v) for v in values])

    def setBoolean(self, vr, values) -> None:
        self._set("set-boolean", "fmi3SetBoolean", vr, [bool(v) for v in values])

    def getReal(self, vr) -> list[float]:
        return self._get("get-float64", "fmi3GetFloat64", vr)

    def getInteger(self, vr) -> list[int]:
        return self._get("get-int32", "fmi3GetInt32", vr)

    def getBoolean(self, vr) -> list[bool]:
        return self._get("get-boolean", "fmi3GetBoolean", vr)

    def getFMUState(self) -> bytes:
        """``get-fmu-state``: the serialized state."""
        return bytes(self._check("fmi3GetFMUState", self.call("get-fmu-state")))

    def setFMUState(self, state: bytes) -> None:
        self._check("fmi3SetFMUState", self.call("set-fmu-state", bytes(state)))

    def doStep(self, currentCommunicationPoint, communicationStepSize,
               noSetFMUStatePriorToCurrentPoint=True) -> None:  # fmt: skip
        """``do-step``; :class:`FMIStatusError` for a status above Warning, and fmi3Discard
        when the component sets ``terminate-simulation`` (the master's clean stop)."""
        out = self.call("do-step", float(currentCommunicationPoint),
                        float(communicationStepSize),
                        bool(noSetFMUStatePriorToCurrentPoint))  # fmt: skip
        if isinstance(out, str):
            raise FMIStatusError("fmi3DoStep", STATUS[out])
        if getattr(out, "terminate-simulation"):
            raise FMIStatusError("fmi3DoStep", 2)


__all__ = ["WasmAdapter", "WasmError", "component_path", "components", "use_components", "wanted"]
