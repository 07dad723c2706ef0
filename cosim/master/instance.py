"""One FMU instance: its unpacked binary, its variables, its FMI calls and its state."""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from glider_fmi.compile import PYTHON_CONFIG_FILE

from ..inputs.archives import InputFileError, read_fmu, safe_extract
from ..inputs.tempdirs import new_temp_dir
from ..inputs.text import did_you_mean, one_line, quote
from . import wasm
from .errors import STATUS, STATUS3, FMUCallError, SystemSpecError, fmi_call_errors
from .fmi3 import TYPE_AS_FMI2, fmi3_call_name

_EXTRACTED: dict[tuple[str, int, int], str] = {}


def _extracted(fmu: Path) -> str:
    """Folder an FMU is unpacked to, once per process and FMU file version.

    Instances of the same FMU share the unpacked binary, and a binary is never unloaded
    (no dlclose): unloading and reloading C++ libraries with thread-local storage while
    other threads (e.g. OpenBLAS's) live can corrupt the heap at process exit. The
    folders are removed at exit.
    """
    st = fmu.stat()
    key = (str(fmu.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _EXTRACTED or not Path(_EXTRACTED[key]).is_dir():
        kept = unpacked_in_cache(fmu)
        if kept is not None:
            _KEPT.add(kept)
            _EXTRACTED[key] = kept
            return kept
        folder = new_temp_dir(f"{fmu.stem[:40]}_")
        try:
            safe_extract(fmu, folder, f"FMU {quote(fmu.name)}")
        except InputFileError:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        _EXTRACTED[key] = str(folder)
    return _EXTRACTED[key]


#: folders of the FMU cache's own unpacked FMUs (:func:`unpacked_in_cache`): kept at exit
_KEPT: set[str] = set()


def in_cache(fmu: Path) -> bool:
    """True for an FMU of the per-user FMU cache, which glider-cosim built: its model
    description is read without schema validation (fmpy's ``validate=False``)."""
    from ..fmus.files import cache_root

    try:
        return fmu.resolve().is_relative_to(cache_root().resolve())
    except OSError:
        return False


def unpacked_in_cache(fmu: Path) -> str | None:
    """The folder an FMU of the per-user cache is unpacked to once for every process:
    ``<cache>/<version>/unpacked/<name>-<SHA-256>`` (unpacked under a temporary name and
    renamed: complete or absent). Unpacking every FMU anew cost a run 30-90 ms (issue
    48). None for an FMU outside the cache (a user's is unpacked in the process's
    temporary folder) or when the cache cannot be written."""
    from ..fmus.files import cache_root, file_sha256, package_version

    if not in_cache(fmu):
        return None
    root = cache_root()
    try:
        final = root / package_version() / "unpacked" / f"{fmu.stem[:40]}-{file_sha256(fmu)[:32]}"
        if final.is_dir():
            return str(final)
        final.parent.mkdir(parents=True, exist_ok=True)
        part = Path(tempfile.mkdtemp(prefix=f".{final.name}-", dir=final.parent))
    except OSError:
        return None
    try:
        safe_extract(fmu, part, f"FMU {quote(fmu.name)}")
        part.rename(final)
    except InputFileError:
        shutil.rmtree(part, ignore_errors=True)
        raise
    except OSError:  # another process unpacked it meanwhile
        shutil.rmtree(part, ignore_errors=True)
    return str(final) if final.is_dir() else None


@atexit.register
def _remove_extracted() -> None:
    for folder in _EXTRACTED.values():
        if folder not in _KEPT:
            shutil.rmtree(folder, ignore_errors=True)


def _fmi2_callbacks(logger: Any) -> Any:
    """fmpy's ``fmi2CallbackFunctions`` with ``logger(env, instance_name, status,
    category, message)`` (the message unformatted: FMI's ``...`` arguments are not read),
    and the C library's ``calloc`` and ``free`` themselves (fmpy's, called from C without
    Python in between); the caller keeps it alive as long as the instance."""
    import fmpy
    from fmpy.fmi2 import (
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
    )

    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(logger)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(
        ctypes.cast(fmpy.calloc, ctypes.c_void_p).value
    )
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(ctypes.cast(fmpy.free, ctypes.c_void_p).value)
    return cb


class Instance:
    """One FMU instance under a name: its model description read by fmpy's
    ``read_model_description``; an FMI 2.0 one on fmpy's ``FMU2Slave``, an FMI 3.0 one on
    fmpy's ``FMU3Slave`` behind :class:`~glider_cosim.master.fmi3.FMU3Adapter` (or its
    WebAssembly component, :class:`~glider_cosim.master.wasm.WasmAdapter`), with batched
    value access."""

    def __init__(self, name: str, fmu: Path):
        self.name = name
        self.fmu = Path(fmu)
        try:  # complete and readable, checked before the binary is loaded
            self.md = read_fmu(self.fmu, f"instance {name}", schema=not in_cache(self.fmu))
        except InputFileError as err:
            raise SystemSpecError(str(err)) from None
        #: FMI version, 2 or 3
        self.fmi = 3 if self.md.fmiVersion.startswith("3") else 2
        if self.fmi == 3:  # Float64, Int32 as Real, Integer (this description is ours)
            for v in self.md.modelVariables:
                v.type = TYPE_AS_FMI2.get(v.type, v.type)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.outputs = [v.name for v in self.md.modelVariables if v.causality == "output"]
        self.inputs = [v.name for v in self.md.modelVariables if v.causality == "input"]
        # outputs that depend directly on inputs (None = all inputs, conservatively)
        self.feedthrough = {
            u.variable.name
            for u in self.md.outputs
            if u.dependencies is None or any(d.causality == "input" for d in u.dependencies)
        }
        # outputs -> the inputs their value in Initialization Mode depends on (the
        # InitialUnknowns' dependencies; None = all inputs, conservatively; an output
        # that is no initial unknown has its start value: none)
        self.initial_inputs: dict[str, set[str] | None] = {
            u.variable.name: None
            if u.dependencies is None
            else {d.name for d in u.dependencies if d.causality == "input"}
            for u in self.md.initialUnknowns
            if u.variable.causality == "output"
        }
        #: its outputs can be got in Initialization Mode (an FMU); an external endpoint
        #: (glider_cosim.realtime.external) answers only after Exit, which sends it the
        #: parameters and the inputs set so far (START)
        self.outputs_before_exit = True
        try:
            self.unzipdir = _extracted(self.fmu)
        except InputFileError as err:
            raise SystemSpecError(f"instance {name}: {err}") from None
        try:
            from fmpy.fmi2 import FMU2Slave

            adapter: Any = FMU2Slave
            if self.fmi == 3 and wasm.wanted():  # run --flavor wasm: the component
                adapter = wasm.WasmAdapter
            elif self.fmi == 3:
                from .fmi3 import FMU3Adapter

                adapter = FMU3Adapter
            self.slave = adapter(
                guid=self.md.guid,
                unzipDirectory=self.unzipdir,
                modelIdentifier=self.md.coSimulation.modelIdentifier,
                instanceName=name,
            )
        except Exception as err:  # noqa: BLE001 - fmpy raises plain Exception here
            raise SystemSpecError(
                f"instance {name}: the binary of {quote(self.fmu.name)} cannot be loaded "
                f"({one_line(err)})"
            ) from None
        self.log: list[str] = []
        self._call_dll: ctypes.CDLL | None = None
        self.alive = False  # instantiated and not fatal
        self.fatal = False
        self.failed = False  # returned fmi2Error: only getters, reset and free are allowed

    @property
    def on_runtime(self) -> bool:
        """The FMU runs on our FMI runtime for Python (the Python flavor), which takes the
        GIL for every call: the C fast loop may call it with the GIL held."""
        return (Path(self.unzipdir) / "resources" / PYTHON_CONFIG_FILE).is_file()

    def call_dll(self) -> Any:
        """The functions the C fast loop (:mod:`~glider_cosim.master.fastloop`) calls for
        this instance, by their FMI 2 names, or None when it cannot call it: for FMI 2,
        the ``dll`` fmpy's ``FMU2Slave`` loaded (the loop takes the functions' addresses
        and passes the instance's ``component``: the very instance fmpy created); for FMI
        3, the shims of :meth:`~glider_cosim.master.fmi3.FMU3Adapter.calls` (None without
        a C compiler); None for a WebAssembly component. The Python path calls the
        instance's object's methods instead.
        """
        if self._call_dll is None:
            if self.fmi == 3:  # the FMI 2-signature shims over the fmi3 calls
                calls = getattr(self.slave, "calls", None)
                self._call_dll = None if calls is None else calls(holds_gil=self.on_runtime)
                return self._call_dll
            self._call_dll = self.slave.dll
        return self._call_dll

    def var(self, name: str, causality: Iterable[str] | None = None):
        v = self.vars.get(name)
        if v is None:
            raise SystemSpecError(
                f"instance {self.name} ({self.md.modelName}) has no variable {quote(name)}"
                + did_you_mean(name, self.vars)
            )
        if causality is not None and v.causality not in causality:
            raise SystemSpecError(
                f"{self.name}.{name} has causality {v.causality}: expected one of "
                f"{', '.join(causality)}"
            )
        return v

    def callbacks(self) -> Any:
        """The callbacks for :meth:`instantiate`, with a logger that keeps the last 50
        messages in :attr:`log` (the caller keeps them alive as long as the instance)."""
        names = STATUS3 if self.fmi == 3 else STATUS

        def logger(env, instance_name, status, category, message):
            # read by FMI's '#' rule (FMI 2.0 section 2.1.5): "##" is a literal '#'
            text = message.decode("utf-8", "replace").replace("##", "#") if message else ""
            self.log.append(f"[{names.get(status, status)}] {text}")
            del self.log[:-50]

        if self.fmi == 3:  # fmi3LogMessageCallback(env, status, category, message)
            from fmpy.fmi3 import fmi3LogMessageCallback

            return fmi3LogMessageCallback(lambda env, st, cat, msg: logger(env, None, st, cat, msg))
        return _fmi2_callbacks(logger)

    def instantiate(self, callbacks: Any, t0: float) -> None:
        """fmi2Instantiate (fmi3InstantiateCoSimulation) with :meth:`callbacks`; raises
        :class:`FMUCallError` at ``t0`` s if it fails. The log starts empty: an earlier
        instance's messages never explain this one's failure."""
        self.log.clear()
        try:
            if self.fmi == 3:
                self.slave.instantiate(log_message=callbacks, loggingOn=True)
            else:
                self.slave.instantiate(callbacks=callbacks, loggingOn=True)
        except Exception as err:  # noqa: BLE001 - fmpy (FMI 3) raises plain Exception here
            call = fmi3_call_name("fmi2Instantiate") if self.fmi == 3 else "fmi2Instantiate"
            raise FMUCallError(self.name, call, t0, 3, self.log, self.fmi) from err
        self.alive = True

    def free(self) -> None:
        """Terminate (unless it failed) and free the instance if it is alive."""
        if self.alive:
            self.alive = False
            slave = self.slave
            if not self.failed:
                with contextlib.suppress(*fmi_call_errors()):
                    slave.terminate()
            # free the instance but keep the library loaded (see _extracted)
            with contextlib.suppress(*fmi_call_errors()):
                slave.fmi2FreeInstance(slave.component)
