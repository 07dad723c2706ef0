"""``glider-cosim serve``: any FMU of a component as a UDP endpoint (:mod:`.protocol`).

One session at a time. A ``START`` (from any address) instantiates the FMU afresh with its
parameters and makes its sender the peer; ``INPUTS`` from the peer step the FMU to the
request's time (in steps of ``h``) and are answered with the outputs; a repeated request
is answered again, an older one dropped; ``STOP`` ends the session. A bad datagram is
dropped (and logged); a refused ``START`` or an ``INPUTS`` of the wrong size is answered
with ``ERROR`` naming what is wrong.
"""

from __future__ import annotations

import logging
import socket
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..master.errors import SystemSpecError, fmi_call_errors
from ..master.instance import Instance
from . import protocol as p

log = logging.getLogger(__name__)


class ServeError(ValueError):
    """The FMU or the address to serve is not usable (what and why is said)."""


class _Session:
    """One instance of the FMU, set up by a ``START``."""

    def __init__(self, inst: Instance, start: p.Message):
        md = inst.md
        self.inst = inst
        self.vars = {v.valueReference: v for v in md.modelVariables}
        self.inputs = [v for v in md.modelVariables if v.causality == "input"]
        self.outputs = [v for v in md.modelVariables if v.causality == "output"]
        if not start.values or len(start.values) % 2 != 1 or not start.values[0] > 0:
            raise p.ProtocolError("malformed: START needs [h, vr, value, ...] with h > 0")
        self.h, self.t0, self.j = start.values[0], start.time, 0
        self.t = self.t0
        self.slave = inst.slave
        inst.log.clear()
        inst.failed = False
        self.callbacks = inst.callbacks()
        inst.instantiate(self.callbacks, self.t0)
        try:
            self.slave.setupExperiment(startTime=self.t0)
            pairs = start.values[1:]
            for vr, value in zip(pairs[::2], pairs[1::2], strict=True):
                v = self.vars.get(int(vr))
                if v is None or v.causality not in ("parameter", "input"):
                    raise p.ProtocolError(f"START sets value reference {int(vr)}: no parameter")
                self._set(v, value)
            self.slave.enterInitializationMode()
            self.slave.exitInitializationMode()
        except fmi_call_errors():
            inst.failed = True  # freed, not terminated (FMI allows nothing else)
            self.close()
            raise
        self.last_seq, self.last_reply = -1, b""

    def _set(self, v: Any, value: float) -> None:
        if v.type == "Real":
            self.slave.setReal([v.valueReference], [value])
        elif v.type == "Integer":
            self.slave.setInteger([v.valueReference], [int(value)])
        else:
            self.slave.setBoolean([v.valueReference], [bool(value)])

    def _get(self, v: Any) -> float:
        vr = [v.valueReference]
        if v.type == "Real":
            return self.slave.getReal(vr)[0]
        if v.type == "Integer":
            return float(self.slave.getInteger(vr)[0])
        return float(self.slave.getBoolean(vr)[0])

    def inputs_message(self, msg: p.Message) -> bytes | None:
        """Step to the request's time, set the inputs, the outputs as a reply."""
        if msg.seq == self.last_seq:
            return self.last_reply  # a duplicate: the same answer again
        if msg.seq < self.last_seq or msg.time < self.t - self.h / 2:
            return None  # older than what was answered: dropped
        if len(msg.values) != len(self.inputs):
            raise p.ProtocolError(
                f"malformed: INPUTS with {len(msg.values)} values, expected "
                f"{len(self.inputs)} ({', '.join(v.name for v in self.inputs)})"
            )
        while self.t < msg.time - self.h / 2:
            self.slave.doStep(self.t, self.h)
            self.j += 1
            self.t = self.t0 + self.j * self.h
        for v, value in zip(self.inputs, msg.values, strict=True):
            self._set(v, value)
        y = [self._get(v) for v in self.outputs]
        self.last_seq, self.last_reply = msg.seq, p.encode(p.OUTPUTS, msg.seq, msg.time, y)
        return self.last_reply

    def close(self) -> None:
        self.inst.free()


def _fmu_error(inst: Instance, err: Exception) -> str:
    """The FMU's own reason for a failed call (its last error message), else the call's
    and its status (the binding's or fmpy's words)."""
    errors = [m for m in inst.log if m.startswith(("[fmi2Error]", "[fmi2Discard]", "[fmi3"))]
    text = " ".join((errors[-1] if errors else str(err)).split())
    return text.partition("] ")[2].removeprefix("served: ") if text.startswith("[") else text


def serve(
    fmu: str | Path,
    listen: str = "udp://127.0.0.1:9870",
    *,
    once: bool = False,
    ready: Callable[[tuple[str, int]], None] | None = None,
    stop: Callable[[], bool] = lambda: False,
) -> int:
    """Serve ``fmu`` (FMI 2.0 co-simulation) on ``listen`` until a signal (or, with
    ``once``, the end of the first session); returns the number of sessions.

    ``ready`` gets the bound address (port 0 picks a free one); ``stop`` is asked about
    twice a second.
    """
    host, port = p.parse_udp(listen, "--listen")
    try:
        inst = Instance("served", Path(fmu))
    except SystemSpecError as err:
        raise ServeError(f"--fmu {str(fmu)!r}: {err}") from None
    fam = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(fam, socket.SOCK_DGRAM)
    try:
        sock.bind((host, port))
    except OSError as err:
        sock.close()
        raise ServeError(f"--listen {listen}: cannot bind ({err.strerror})") from None
    sessions = 0
    session: _Session | None = None
    peer = None
    if ready is not None:
        ready(sock.getsockname()[:2])
    sock.settimeout(0.5)
    try:
        while not stop():
            try:
                data, addr = sock.recvfrom(p.MAX_SIZE + 1)
            except TimeoutError:
                continue
            reply = None
            try:
                msg = p.decode(data)
            except p.ProtocolError as err:
                log.warning("serve: datagram from %s dropped: %s", addr, err)
                continue
            try:
                if msg.type == p.START:
                    if session is not None:
                        session.close()
                    session, peer = None, addr
                    session = _Session(inst, msg)
                    sessions += 1
                    reply = p.encode(p.READY, msg.seq, msg.time)
                elif addr != peer or session is None:
                    log.warning("serve: %s from %s dropped: no session", p.TYPES[msg.type], addr)
                elif msg.type == p.INPUTS:
                    reply = session.inputs_message(msg)
                elif msg.type == p.STOP:
                    session.close()
                    session, peer = None, None
                    if once:
                        break
            except p.ProtocolError as err:
                log.warning("serve: %s: %s", addr, err)
                reply = p.encode_error(msg.seq, msg.time, f"refused: {err}")
            except fmi_call_errors() as err:
                text = _fmu_error(inst, err)
                log.warning("serve: %s", text)
                reply = p.encode_error(msg.seq, msg.time, f"refused: {text}")
                if session is not None:
                    inst.failed = True
                    session.close()
                session, peer = None, None
            if reply is not None:
                sock.sendto(reply, addr)
    finally:
        if session is not None:
            session.close()
        sock.close()
    return sessions
