"""Paced runs: communication points held to the wall clock at a real-time factor.

Point ``k`` is due at ``T0 + k*h/rtf`` on the monotonic clock (``time.monotonic_ns``).
The master sleeps until ``spin_ms`` before the deadline (1.5 ms by default), then spins
to it; a ``spin_ms`` of one period or more never sleeps (it keeps a core busy, and holds
the deadlines where waking from a sleep is slow, as on a virtual machine). Overrun policy:
simulated time is kept (no step is skipped or stretched) and the deadlines stay on their
grid, so a late point is followed by points that start at once, without sleeping, until
the run has caught up; every step whose work (exchange, recording and ``doStep``) ends
after the next point's deadline is counted as an overrun. With ``max_lateness_ms`` a
point that starts later than that stops the run cleanly (:class:`TooLate`).
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..master.errors import Interrupted, MasterError, SystemSpecError, deferred_sigint
from ..master.spec import Recorder, count_steps

#: how long before a deadline the pacer stops sleeping and spins by default, ms
SPIN_MS = 1.5


class TooLate(MasterError, RuntimeError):
    """A communication point started later than ``--max-lateness-ms`` allows.

    Attributes ``time`` (simulated, s), ``lateness_ms`` and ``limit_ms``.
    """

    def __init__(self, time_s: float, lateness_ms: float, limit_ms: float):
        self.time, self.lateness_ms, self.limit_ms = time_s, lateness_ms, limit_ms
        super().__init__(
            f"real time: the communication point at t = {time_s:.6g} s started "
            f"{lateness_ms:.3f} ms late, more than --max-lateness-ms {limit_ms:g}"
        )


@dataclass
class RealTime:
    """How a run is paced.

    Parameters
    ----------
    rtf : float
        Target real-time factor: simulated seconds per wall-clock second (1 real time,
        0.5 half speed, 2 twice as fast).
    max_lateness_ms : float or None
        Stop the run when a communication point starts later than this, ms.
    spin_ms : float
        How long before each deadline the pacer stops sleeping and spins, ms (0: it only
        sleeps; a period or more: it never sleeps and keeps a core busy).
    """

    rtf: float = 1.0
    max_lateness_ms: float | None = None
    spin_ms: float = SPIN_MS

    def __post_init__(self) -> None:
        _check("rtf", self.rtf, zero=False, unit="")
        if self.max_lateness_ms is not None:
            _check("max_lateness_ms", self.max_lateness_ms, zero=False, unit=" (ms)")
        _check("spin_ms", self.spin_ms, zero=True, unit=" (ms)")


def _check(name: str, value: Any, zero: bool, unit: str) -> None:
    """Refuse ``value`` unless it is a finite number > 0 (``zero``: >= 0)."""
    ok = not isinstance(value, bool) and isinstance(value, int | float) and math.isfinite(value)
    if not (ok and (value >= 0 if zero else value > 0)):
        raise SystemSpecError(
            f"{name} {value!r} is invalid: expected a finite number {'>=' if zero else '>'} 0"
            + unit
        )


class Pacer:
    """Deadlines of the communication points of one run, and what was measured.

    Parameters
    ----------
    step : float
        Communication step, s (simulated).
    real_time : RealTime
        Target factor and lateness limit.
    t0 : float
        Simulated start time, s (for :class:`TooLate`'s message).
    """

    def __init__(self, step: float, real_time: RealTime, t0: float = 0.0):
        self.period_ns = step / real_time.rtf * 1e9
        self.step, self.t0, self.real_time = step, t0, real_time
        self.limit_ns = (
            None if real_time.max_lateness_ms is None else real_time.max_lateness_ms * 1e6
        )
        self.spin_ns = round(real_time.spin_ms * 1e6)
        self.start_ns = 0
        self.last_ns = 0
        self.lateness_ns: list[int] = []
        self.overruns = 0

    def deadline(self, k: int) -> int:
        """When point ``k`` is due, ns on the monotonic clock."""
        return self.start_ns + round(k * self.period_ns)

    def start(self) -> None:
        """Point 0 is due now."""
        self.start_ns = time.monotonic_ns()

    def wait(self, k: int) -> None:
        """Sleep, then spin, until point ``k`` is due; record how late it starts."""
        due = self.deadline(k)
        now = time.monotonic_ns()
        if due - now > self.spin_ns:
            time.sleep((due - now - self.spin_ns) / 1e9)
        while (now := time.monotonic_ns()) < due:
            pass
        late = now - due
        self.lateness_ns.append(late)
        self.last_ns = now
        if self.limit_ns is not None and late > self.limit_ns:
            raise TooLate(self.t0 + k * self.step, late / 1e6, self.real_time.max_lateness_ms)

    def done(self, k: int) -> None:
        """The work of step ``k`` ended: an overrun if point ``k + 1`` is already due."""
        if time.monotonic_ns() > self.deadline(k + 1):
            self.overruns += 1

    def summary(self) -> dict[str, Any]:
        """``metrics.json``'s ``real_time``: factors, lateness percentiles (ms), overruns."""
        import numpy as np  # percentiles, for a paced run only

        late = np.asarray(self.lateness_ns, dtype=float) / 1e6
        n = len(late)
        wall = (self.last_ns - self.start_ns) / 1e9
        achieved = (n - 1) * self.step / wall if n > 1 and wall > 0 else None
        pct = {
            "p50": float(np.percentile(late, 50)) if n else None,
            "p99": float(np.percentile(late, 99)) if n else None,
            "max": float(late.max()) if n else None,
        }
        out = {
            "rtf_target": self.real_time.rtf,
            "rtf_achieved": achieved,
            "points": n,
            "lateness_ms": pct,
            "overruns": self.overruns,
            "max_lateness_ms": self.real_time.max_lateness_ms,
            "spin_ms": self.real_time.spin_ms,
            "overrun_policy": "keep simulated time; catch up without sleeping; count",
        }
        return out


def describe(rt: dict[str, Any]) -> str:
    """``metrics.json``'s ``real_time`` in one line (the run summary's)."""
    lat = rt["lateness_ms"]

    def ms(v: float | None) -> str:
        return "n/a" if v is None else f"{v:.3f}"

    achieved = rt["rtf_achieved"]
    text = (
        f"real time: rtf {'n/a' if achieved is None else f'{achieved:.3f}'} "
        f"(target {rt['rtf_target']:g}), lateness p50 {ms(lat['p50'])} ms, p99 "
        f"{ms(lat['p99'])} ms, max {ms(lat['max'])} ms, {rt['overruns']} overruns"
    )
    for name, ext in rt.get("external", {}).items():
        text += f"; {name}: {ext['late_replies']} late or missing replies held"
    return text


def paced_run(
    sim: Any,
    stop_time: float,
    recorder: Recorder,
    pacer: Pacer,
    on_step: Callable[[int], None] | None = None,
) -> None:
    """:meth:`~glider_cosim.master.CoSimulation.run` with every point paced by ``pacer``.

    It steps from Python one point at a time (the exchange and ``doStep`` still go
    through the master's planned C calls when it has them, but never whole blocks of
    steps in C), so the rows are those of an unpaced run. Raises as ``run`` does, and
    :class:`TooLate`, after the rows so far were handed to ``recorder``.

    Python's cyclic garbage collector must not stop a paced loop for milliseconds: every
    object that exists when the loop starts is collected once and then frozen
    (:func:`gc.freeze`) for the loop, so a collection during it walks only what the loop
    made (a full collection of the process's objects takes several ms); they are unfrozen
    when the loop ends, however it ends.
    """
    n = count_steps(stop_time - sim.t0, sim.step_size, sim.max_steps)
    gc.collect()
    gc.freeze()
    try:
        _paced_points(sim, n, recorder, pacer, on_step)
    finally:
        gc.unfreeze()


def _paced_points(
    sim: Any, n: int, recorder: Recorder, pacer: Pacer, on_step: Callable[[int], None] | None
) -> None:
    with deferred_sigint() as interrupted:
        sim.initialize()
        recorder.start(sim.columns)
        pacer.start()
        pacer.wait(0)
        recorder.row(sim.communication_point())
        for k in range(n):
            if signum := interrupted():
                raise Interrupted(signum)
            if on_step is not None:
                on_step(k)
            sim.do_step()
            pacer.done(k)
            pacer.wait(k + 1)
            recorder.row(sim.communication_point())
