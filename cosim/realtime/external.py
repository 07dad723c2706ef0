"""Components outside the process: the master's side of a UDP endpoint.

:func:`attach` replaces an instance of a loaded co-simulation by an endpoint. The
instance keeps its model description (names, value references, order); its calls go to
:class:`ExternalSlave`. Inputs set by the master are kept; the first read after a change
or a step sends them (``INPUTS`` at the point's time, :mod:`.protocol`) and waits for the
outputs; a step with inputs the endpoint does not hold yet sends them first. A component
whose outputs depend on its inputs (our controller) thus costs one round trip per step.

Lockstep (no pacer): each reply is awaited, up to ``timeout`` s, the request sent again
(same sequence number; the endpoint answers a repeat as the first time) every
:data:`RESEND_S` s, so a lost datagram costs time, not the result. Real time (a pacer):
each reply is awaited until the next point's deadline; a late or missing one keeps the
last outputs and is counted (``late_replies``). Either way an endpoint silent for longer
than ``timeout`` stops the run (:class:`EndpointError`). Datagrams from another address,
malformed, of a wrong version, or stale (an older sequence number: a duplicate, a late or
reordered reply) are dropped and counted.
"""

from __future__ import annotations

import logging
import socket
import time
from dataclasses import dataclass
from typing import Any

from ..components import COMPONENTS, names_in_words
from ..master.errors import MasterError
from . import protocol as p

log = logging.getLogger(__name__)

#: seconds an endpoint may stay silent before the run stops (``--external-timeout``)
DEFAULT_TIMEOUT = 5.0
#: lockstep: seconds without a reply before the request is sent again (same number)
RESEND_S = 0.05


class EndpointError(MasterError, RuntimeError):
    """An external endpoint failed: silent past its timeout, refused the start, or said an
    error. The message names the component and its address."""


@dataclass
class Endpoint:
    """Where a component is served: ``udp://HOST:PORT``, and its silence timeout, s."""

    url: str
    timeout: float = DEFAULT_TIMEOUT

    def __post_init__(self) -> None:
        self.address = p.parse_udp(self.url)
        if not self.timeout > 0:
            raise ValueError(f"timeout {self.timeout!r} is invalid: expected a number > 0 (s)")


def parse_external(items: list[str]) -> dict[str, str]:
    """``--external COMPONENT=udp://HOST:PORT`` items -> ``{component: url}``."""
    out = {}
    for item in items:
        name, sep, url = item.partition("=")
        if not sep or name.strip() not in [c.name for c in COMPONENTS]:
            raise ValueError(
                f"--external {item!r} is invalid: expected {names_in_words()}=udp://HOST:PORT"
            )
        p.parse_udp(url.strip(), f"--external {name.strip()}")
        out[name.strip()] = url.strip()
    return out


class ExternalSlave:
    """The calls of one instance, answered by an endpoint (the methods of fmpy's
    ``FMU2Slave`` that the master calls; no C fast loop)."""

    dll = None
    component = None

    def __init__(self, inst: Any, endpoint: Endpoint, pacer: Any = None):
        self.name, self.endpoint, self.pacer = inst.name, endpoint, pacer
        self.where = f"{inst.name} ({endpoint.url})"
        self.inputs = list(inst.inputs)
        self.outputs = list(inst.outputs)
        vr_of = {n: v.valueReference for n, v in inst.vars.items()}
        self.in_index = {vr_of[n]: i for i, n in enumerate(self.inputs)}
        self.out_index = {vr_of[n]: i for i, n in enumerate(self.outputs)}
        self.u = [0.0] * len(self.inputs)
        self.y = [0.0] * len(self.outputs)
        self.params: dict[int, float] = {}
        self.sock: socket.socket | None = None
        self.seq, self.k, self.t0, self.h = 0, 0, 0.0, 0.0
        self.dirty = self.stale_out = True
        self.counts = dict.fromkeys(
            ("round_trips", "late_replies", "resent", "stale", "malformed", "foreign"), 0
        )
        self.rtt_ns: list[int] = []
        self.last_heard = 0.0

    # -------------------------------------------------------- set-up (fmpy's names)
    def instantiate(self, **_: Any) -> None:
        """Open the socket (an ephemeral port of the endpoint's family)."""
        fam = socket.AF_INET6 if ":" in self.endpoint.address[0] else socket.AF_INET
        self.sock = socket.socket(fam, socket.SOCK_DGRAM)
        self.sock.bind(("::1" if fam == socket.AF_INET6 else "127.0.0.1", 0)
                       if self.endpoint.address[0] in ("127.0.0.1", "::1", "localhost")
                       else ("", 0))  # fmt: skip
        self.peer = socket.getaddrinfo(*self.endpoint.address, fam, socket.SOCK_DGRAM)[0][4][:2]

    def setupExperiment(self, tolerance: Any, start_time: float) -> None:  # noqa: N802
        self.t0, self.k = float(start_time), 0

    def _keep(self, vrs: list[int], values: list[Any]) -> None:
        for vr, v in zip(vrs, values, strict=True):
            if vr in self.in_index:
                self.u[self.in_index[vr]] = float(v)
                self.dirty = True  # after START: sent with the next exchange
            self.params[vr] = float(v)

    setReal = setInteger = setBoolean = _keep  # noqa: N815

    def enterInitializationMode(self) -> None:  # noqa: N802
        pass

    def exitInitializationMode(self) -> None:  # noqa: N802
        """Send ``START`` with the step and the parameters; wait for ``READY``."""
        values = [self.h]
        for vr, v in self.params.items():
            values += [float(vr), v]
        reply = self._request(p.START, self.t0, values, p.READY, lockstep=True)
        if reply is None:  # pragma: no cover - lockstep waits or raises
            raise EndpointError(f"{self.where}: no answer to START")
        self.dirty = self.stale_out = True

    def terminate(self) -> None:
        if self.sock is not None:
            self.sock.sendto(p.encode(p.STOP, self.seq + 1, self._t()), self.peer)

    def fmi2FreeInstance(self, component: Any) -> None:  # noqa: N802
        if self.sock is not None:
            self.sock.close()
            self.sock = None

    def reset(self) -> None:
        raise EndpointError(f"{self.where}: an external component cannot be reset")

    # ------------------------------------------------------------------ per step
    def _t(self) -> float:
        return self.t0 + self.k * self.h

    def doStep(self, t: float, h: float, flag: Any = True) -> None:  # noqa: N802
        """The endpoint steps with the inputs of this point (sent first if changed)."""
        if self.dirty:
            self._exchange()
        self.k += 1
        self.stale_out = True

    def getReal(self, vrs: list[int]) -> list[float]:  # noqa: N802
        """Outputs at the current point: an exchange with the inputs set so far (unless
        done since they were set). In the master's Initialization Mode (after START,
        before the first step) it is made in lockstep whatever the pacing; at the steps
        after, paced."""
        if self.dirty or self.stale_out:
            self._exchange(lockstep=self.k == 0)
        return [self.y[self.out_index[vr]] for vr in vrs]

    getInteger = getBoolean = getReal  # noqa: N815

    def _exchange(self, lockstep: bool = False) -> None:
        lockstep = lockstep or self.pacer is None
        reply = self._request(p.INPUTS, self._t(), self.u, p.OUTPUTS, lockstep)
        if reply is not None:
            if len(reply.values) != len(self.y):
                raise EndpointError(
                    f"{self.where}: OUTPUTS with {len(reply.values)} values, expected "
                    f"{len(self.y)} ({', '.join(self.outputs)})"
                )
            self.y = reply.values
        self.dirty = self.stale_out = False

    def _request(self, kind: int, t: float, values: list[float], want: int, lockstep: bool):
        """Send one request; its reply, or None when it is late (real time)."""
        assert self.sock is not None
        self.seq += 1
        seq = self.seq
        sent = time.monotonic_ns()
        if not self.last_heard:
            self.last_heard = time.monotonic()
        packet = p.encode(kind, seq, t, values)
        self.sock.sendto(packet, self.peer)
        # real time: the reply is due half a period after the point's deadline
        until = None if lockstep else (self.pacer.deadline(self.k) + self.pacer.period_ns / 2) / 1e9
        resend = time.monotonic() + RESEND_S
        while True:
            now = time.monotonic()
            if until is None and now >= resend:
                self.sock.sendto(packet, self.peer)
                self.counts["resent"] += 1
                resend = now + RESEND_S
            silent_until = self.last_heard + self.endpoint.timeout
            due = min(silent_until, resend) if until is None else min(until, silent_until)
            wait = due - now
            if now >= silent_until:
                raise EndpointError(
                    f"{self.where}: no reply for {self.endpoint.timeout:g} s "
                    "(--external-timeout): the run stops"
                )
            if wait <= 0:
                if until is None:
                    continue  # lockstep: time to send again
                self.counts["late_replies"] += 1
                return None
            self.sock.settimeout(wait)
            try:
                data, addr = self.sock.recvfrom(p.MAX_SIZE + 1)
            except TimeoutError:
                continue
            except ConnectionRefusedError:
                continue  # an ICMP port unreachable: silence until the timeout
            if addr[:2] != self.peer:
                self.counts["foreign"] += 1
                continue
            try:
                msg = p.decode(data)
            except p.ProtocolError as err:
                self.counts["malformed"] += 1
                log.warning("%s: datagram dropped: %s", self.where, err)
                continue
            if msg.type == p.ERROR and msg.seq == seq:
                raise EndpointError(f"{self.where}: {msg.text}")
            if msg.seq != seq or msg.type != want:
                self.counts["stale"] += 1
                continue
            self.last_heard = time.monotonic()
            self.rtt_ns.append(time.monotonic_ns() - sent)
            self.counts["round_trips"] += 1
            return msg

    def summary(self) -> dict[str, Any]:
        """Counters and the round trip (p50, p99, max, ms) for ``metrics.json``."""
        rtt = sorted(self.rtt_ns)
        out: dict[str, Any] = {"endpoint": self.endpoint.url, **self.counts}
        out["rtt_ms"] = {
            "p50": rtt[len(rtt) // 2] / 1e6 if rtt else None,
            "p99": rtt[min(len(rtt) - 1, len(rtt) * 99 // 100)] / 1e6 if rtt else None,
            "max": rtt[-1] / 1e6 if rtt else None,
        }
        return out


def attach(sim: Any, external: dict[str, Any], pacer: Any = None) -> dict[str, ExternalSlave]:
    """Replace the instances named in ``external`` (name -> url or :class:`Endpoint`) of a
    co-simulation whose model descriptions are read (before its plan); sets
    ``sim.external`` (name -> :class:`ExternalSlave`)."""
    slaves = {}
    for name, ep in external.items():
        if name not in sim.instances:
            raise ValueError(
                f"--external {name}: no such instance (instances: {', '.join(sim.instances)})"
            )
        endpoint = ep if isinstance(ep, Endpoint) else Endpoint(ep)
        inst = sim.instances[name]
        slave = ExternalSlave(inst, endpoint, pacer)
        slave.h = sim.step_size
        inst.slave = slave
        inst.outputs_before_exit = False  # the endpoint starts at Exit (START)
        slaves[name] = slave
    sim.external = slaves
    return slaves
