"""The master's typed errors (ill-formed system, failed FMI call, interrupted run), and Ctrl-C."""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Sequence

#: FMI 2.0 status names, by value (the FMI 3.0 ones in :data:`STATUS3`)
STATUS = {0: "fmi2OK", 1: "fmi2Warning", 2: "fmi2Discard", 3: "fmi2Error", 4: "fmi2Fatal"}
STATUS3 = {k: v.replace("fmi2", "fmi3") for k, v in STATUS.items()}


class MasterError(Exception):
    """Base of the master's errors."""


class SystemSpecError(MasterError, ValueError):
    """The system is ill-formed: unknown instance or variable, type mismatch, input left
    unconnected, algebraic loop, bad step or stop time."""


class FMUCallError(MasterError, RuntimeError):
    """An FMI call returned fmi2Error or fmi2Fatal (fmi3Error, fmi3Fatal).

    Attributes ``instance``, ``call``, ``time`` (s), ``status``, ``log`` (the FMU's own
    messages for that instance since it was instantiated or last reset: this run's) and
    ``fmi`` (the FMI version, 2 or 3: the call and the status are named in its terms).
    """

    def __init__(
        self, instance: str, call: str, time: float, status: int, log: Sequence[str], fmi: int = 2
    ):
        self.instance, self.call, self.time, self.status = instance, call, time, status
        self.log = list(log)
        self.fmi = fmi
        names = STATUS3 if fmi == 3 else STATUS
        errors = [m for m in self.log if m.startswith((f"[{names[3]}]", f"[{names[2]}]"))]
        detail = (errors[0] if errors else self.log[-1]) if self.log else "no log message"
        detail = " ".join(detail.split())
        # the FMU's message often starts with the instance's and the call's names (ours
        # do), which are said already
        status_tag, _, text = detail.partition("] ")
        base = call.partition("(")[0]
        if text.startswith(f"{instance}: {base}: "):
            text = text.removeprefix(f"{instance}: ")
            detail = f"{status_tag}] {text}"
        if text.startswith(f"{base}: "):
            detail = f"{status_tag}] {text[len(base) + 2 :]}"
        super().__init__(
            f"{instance}: {call} at t = {time:.6g} s returned {names.get(status, status)}: {detail}"
        )


class FMIStatusError(RuntimeError):
    """An FMI function returned a status worse than Warning (or fmi2Instantiate NULL), as
    the FMI 3 and wasm adapters raise it (fmpy's own calls raise its ``FMICallException``,
    with the same ``function`` and ``status``); the master turns it into
    :class:`FMUCallError` or :class:`FMUStopped` with the instance, the time and the FMU's
    log. Attributes ``call`` (also ``function``, fmpy's
    name) and ``status``."""

    def __init__(self, call: str, status: int):
        self.call = self.function = call
        self.status = int(status)
        super().__init__(f"{call} returned {STATUS.get(self.status, self.status)}")


def fmi_call_errors() -> tuple[type[BaseException], ...]:
    """What a failed FMI call raises: :class:`FMIStatusError`, and fmpy's
    ``FMICallException`` once fmpy is imported (it is whenever an FMU is loaded; this
    module, which the command line's parser imports, does not import it)."""
    fmi1 = sys.modules.get("fmpy.fmi1")
    fmpy_error = getattr(fmi1, "FMICallException", None)
    return (FMIStatusError,) if fmpy_error is None else (FMIStatusError, fmpy_error)


class FMUStopped(FMUCallError):
    """An FMI call returned fmi2Discard (fmi3Discard, or fmi3DoStep set
    terminateSimulation): the FMU stopped the run cleanly (e.g. a stall)."""


class Interrupted(KeyboardInterrupt):
    """The run was stopped by SIGINT (Ctrl-C) or SIGTERM at a communication point.

    ``signum`` is the signal's number; ``result`` what the run returned before it was
    raised (a :class:`~glider_cosim.runner.RunResult`, or None); ``kept`` says, for the
    console, where the results so far are and how to go on (set by the command, e.g.
    ``37 of 240 runs in out/sweep/sweep.csv; resume with: glider-cosim sweep ...``).
    """

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signum)
        self.signum = int(signum)
        self.result: object = None
        self.kept = ""

    def describe(self) -> str:
        """``"interrupted by the user (Ctrl-C)"`` or ``"terminated (SIGTERM)"``."""
        if self.signum == signal.SIGTERM:
            return "terminated (SIGTERM)"
        return "interrupted by the user (Ctrl-C)"


#: the signals :func:`deferred_sigint` turns into a flag, as plain ints
_DEFERRED = (int(signal.SIGINT), int(signal.SIGTERM))
try:  # CPython's C function under signal.signal, without its enum conversions: a run
    # installs and restores two handlers, 20 us through signal.signal, 2 us through it
    from _signal import signal as _set_handler
except ImportError:  # pragma: no cover - another Python
    _set_handler = signal.signal


@contextlib.contextmanager
def deferred_sigint():
    """Turn Ctrl-C and SIGTERM into a flag checked between steps (main thread only).

    A KeyboardInterrupt raised inside an FMU's Python code would become fmi2Fatal; the
    master stops at the next communication point instead and raises
    :class:`Interrupted` there. Yields a function returning the signal number or 0.
    """
    if threading.current_thread() is not threading.main_thread():
        yield lambda: 0
        return
    flag: list[int] = []

    def handler(signum, frame):
        flag.append(signum)

    old = {sig: _set_handler(sig, handler) for sig in _DEFERRED}
    try:
        yield lambda: flag[0] if flag else 0
    finally:
        for sig, h in old.items():
            _set_handler(sig, h)
