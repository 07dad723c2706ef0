"""The master's per-step FMI calls in C: one ctypes call per exchange and per step.

:class:`CoSimulation` plans its exchange as a list of batched Real gets and sets in a
fixed order (see :mod:`glider_cosim.master.plan`). Run from Python, every one of them is a
call of the instance's fmpy object (``FMU2Slave.getReal``, ``setReal``, ``doStep``: a few
microseconds each, 12 per macro step for the glider loop). Here the plan is
handed to a small C function (``fastloop.c``, compiled once per FMU cache, into
``<cache>/<version>/fastloop-<hash>/``, with the build's toolchain: zig's C compiler by
default, see :mod:`glider_fmi.toolchain`) that makes the same FMI calls, in the same
order, with the same arrays; a write's values are copied from the read arrays they come
from. The C loop calls the very instances fmpy created: the function addresses come from
the ``dll`` fmpy loaded, the instance from its ``component``. The results are bit for bit
those of the Python path (tested), which remains the path when the plan has non-Real
groups, an instance the C loop cannot call (a WebAssembly component, an external
endpoint), no compiler is found, or ``GLIDER_COSIM_FASTLOOP=0``.
"""

from __future__ import annotations

import ctypes
import os
import subprocess
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..fmus.helpers import build_helper

SOURCE = Path(__file__).with_name("fastloop.c")
#: the files compiled into the helper
SOURCES = (SOURCE,)
#: the headers they include (in the build's hash too)
HEADERS: tuple[Path, ...] = ()
ENV = "GLIDER_COSIM_FASTLOOP"
#: the helper's compile flags (after the toolchain's shared-library ones)
FLAGS = ("-O2", "-ffp-contract=off", *(() if os.name == "nt" else ("-pthread",)))
_LIB: dict[bool, ctypes.CDLL | None] = {}


class _Op(ctypes.Structure):
    _fields_ = [
        ("fn", ctypes.c_void_p),
        ("comp", ctypes.c_void_p),
        ("vr", ctypes.c_void_p),
        ("n", ctypes.c_size_t),
        ("values", ctypes.c_void_p),
        ("sources", ctypes.c_void_p),
    ]


def library(release_gil: bool = False) -> ctypes.CDLL | None:
    """The compiled helper for code that only formats (no FMI calls), or None.

    Parameters
    ----------
    release_gil : bool
        Load it as ``ctypes.CDLL`` (its calls release the GIL: for a thread formatting
        while another one runs), else as ``ctypes.PyDLL`` (cheaper calls).
    """
    if os.environ.get(ENV, "1") == "0":
        return None
    return _library(not release_gil)


#: the FMI 2.0-signature shims over an FMI 3.0 instance (``fastloop.c``), by the call
#: they stand for
SHIMS = {
    "fmi2GetReal": "glider_shim_get_float64",
    "fmi2SetReal": "glider_shim_set_float64",
    "fmi2GetInteger": "glider_shim_get_int32",
    "fmi2SetInteger": "glider_shim_set_int32",
    "fmi2GetBoolean": "glider_shim_get_boolean",
    "fmi2SetBoolean": "glider_shim_set_boolean",
    "fmi2DoStep": "glider_shim_do_step",
}


def shim_library(hold_gil: bool) -> ctypes.CDLL | None:
    """The compiled helper for its FMI 3 shims (whatever ``GLIDER_COSIM_FASTLOOP`` says:
    the master's Python loop calls them too), or None without a C compiler."""
    return _library(hold_gil)


def _library(hold_gil: bool) -> ctypes.CDLL | None:
    """The compiled helper (``PyDLL`` when the FMUs run Python under the GIL anyway)."""
    if hold_gil in _LIB:
        return _LIB[hold_gil]
    lib = None
    try:
        out = built_library()
        lib = (ctypes.PyDLL if hold_gil else ctypes.CDLL)(str(out))
        lib.glider_exchange.restype = lib.glider_step.restype = ctypes.c_int
        lib.glider_run.restype = ctypes.c_long
        for name in SHIMS.values():
            getattr(lib, name).restype = ctypes.c_int
    except (OSError, subprocess.SubprocessError):
        lib = None  # the Python loop runs instead
    _LIB[hold_gil] = lib
    return lib


def built_library() -> Path:
    """The compiled helper, built once per FMU cache (:func:`glider_cosim.fmus.folders.
    cache_root`): ``<cache>/<version>/fastloop-<hash>/fastloop<suffix>`` (see
    :func:`glider_cosim.fmus.helpers.build_helper`).

    Raises
    ------
    OSError
        No compiler for this machine, or it failed.
    """
    return build_helper("fastloop", SOURCES, HEADERS, FLAGS, "the master's C loop")


def fast_loop_wanted() -> bool:
    """False when ``GLIDER_COSIM_FASTLOOP=0`` asks for the master's Python path (every
    call through the instances' fmpy objects)."""
    return os.environ.get(ENV, "1") != "0"


class FastLoop:
    """A planned exchange and the steps of all instances, run in C.

    Parameters
    ----------
    ops : sequence
        The master's exchange plan: ``(read, inst, fn, call, comp, vr, n, value, names,
        sources)`` per batched call, in order (``names``: for a read the variables it
        reads, for a write the ``instance.variable`` each value comes from).
    steppers : sequence
        ``(inst, fmi2DoStep, comp)`` per instance.
    hold_gil : bool
        Call with the GIL held (every FMU runs on our runtime).
    """

    def __init__(self, ops: Sequence[tuple], steppers: Sequence[tuple], lib: ctypes.CDLL):
        self._lib = lib
        where: dict[str, tuple[Any, int]] = {}  # output -> (array, index) it is read into
        for read, _inst, _fn, _call, _comp, _vr, _n, value, names, _src in ops:
            if read:
                for k, name in enumerate(names):
                    where[name] = (value, k)
        self._keep: list[Any] = []
        self._ops = (_Op * len(ops))()
        for i, (read, _inst, fn, _call, comp, vr, n, value, names, _src) in enumerate(ops):
            sources = None
            if not read:
                ptrs = (ctypes.c_void_p * len(names))()
                for k, src in enumerate(names):
                    arr, j = where[src]
                    ptrs[k] = ctypes.addressof(arr) + j * ctypes.sizeof(ctypes.c_double)
                self._keep.append(ptrs)
                sources = ctypes.addressof(ptrs)
            self._ops[i] = _Op(ctypes.cast(fn, ctypes.c_void_p).value, comp.value,
                               ctypes.addressof(vr), n.value, ctypes.addressof(value),
                               sources)  # fmt: skip
        self._nops = ctypes.c_int(len(ops))
        self._fns = (ctypes.c_void_p * len(steppers))(
            *(ctypes.cast(fn, ctypes.c_void_p).value for _, fn, _ in steppers)
        )
        self._comps = (ctypes.c_void_p * len(steppers))(*(c.value for _, _, c in steppers))
        self._nsteps = ctypes.c_int(len(steppers))
        self._status = ctypes.c_int(0)
        self._status_ref = ctypes.byref(self._status)
        self._where = ctypes.c_int(0)
        self._index = ctypes.c_int(0)
        self._where_of = where
        self._record: Any = None

    @classmethod
    def plan(
        cls, ops: Sequence[tuple], steppers: Sequence[tuple], hold_gil: bool
    ) -> FastLoop | None:
        """A :class:`FastLoop` for the plan, or None where the Python loop must run."""
        if not fast_loop_wanted():
            return None
        if any(op[7]._type_ is not ctypes.c_double for op in ops):
            return None
        fns = [op[2] for op in ops] + [fn for _, fn, _ in steppers]
        if not all(isinstance(fn, ctypes._CFuncPtr) for fn in fns):
            return None  # Python stand-ins (FMI 3 shims without a C compiler)
        for read, _inst, _fn, _call, _comp, _vr, _n, _value, names, _src in ops:
            if not read and any("." not in s for s in names):
                return None
        lib = _library(hold_gil)
        if lib is None:
            return None
        try:
            return cls(ops, steppers, lib)
        except KeyError:  # a write from a value no read of the plan provides
            return None

    def exchange(self) -> tuple[int, int]:
        """The planned gets and sets: ``(index of the failed call or -1, its status)``."""
        i = self._lib.glider_exchange(self._ops, self._nops, self._status_ref)
        return i, self._status.value

    def step(self, t: ctypes.c_double, h: ctypes.c_double) -> tuple[int, int]:
        """fmi2DoStep of every instance: ``(index of the failed one or -1, its status)``."""
        i = self._lib.glider_step(self._fns, self._comps, self._nsteps, t, h, self._status_ref)
        return i, self._status.value

    def record(self, names: Sequence[str]) -> bool:
        """Record ``names`` (outputs the exchange reads) in :meth:`run`'s rows; False if
        one of them is not read by the plan."""
        if any(n not in self._where_of for n in names):
            return False
        ptrs = (ctypes.c_void_p * max(1, len(names)))()
        for c, name in enumerate(names):
            arr, j = self._where_of[name]
            ptrs[c] = ctypes.addressof(arr) + j * ctypes.sizeof(ctypes.c_double)
        self._record = ptrs
        self._nrec = len(names)
        self._rows = (ctypes.c_double * (self.RUN_BLOCK * (len(names) + 1)))()
        return True

    #: macro steps one :meth:`run` call makes at most
    RUN_BLOCK = 256

    def run(self, t0: float, k: int, h: float, n: int) -> tuple[int, int, int, int]:
        """Up to ``n`` (<= RUN_BLOCK) macro steps from step ``k``, each followed by the
        exchange and a recorded row in :attr:`rows`: ``(rows done, where, index, status)``
        with ``where`` -1 when all went well, 0 a failed doStep, 1 a failed exchange."""
        done = self._lib.glider_run(
            self._ops, self._nops, self._fns, self._comps, self._nsteps, ctypes.c_double(t0),
            ctypes.c_long(k), ctypes.c_double(h), ctypes.c_long(n), self._record,
            ctypes.c_int(self._nrec), self._rows, ctypes.byref(self._where),
            ctypes.byref(self._index), self._status_ref,
        )  # fmt: skip
        if done == n:
            return done, -1, -1, 0
        return done, self._where.value, self._index.value, self._status.value

    @property
    def rows(self) -> Any:
        """The row buffer :meth:`run` fills (ctypes doubles, time first in each row)."""
        return self._rows
