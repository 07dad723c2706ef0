"""The endpoint message format (version 1): the reference codec, in Python.

Every message is one UDP datagram, little-endian, a 24-byte header then a payload::

    offset size type     field
     0     4    bytes    magic b"GCSM"
     4     1    uint8    version (1)
     5     1    uint8    type (START 1, READY 2, INPUTS 3, OUTPUTS 4, ERROR 5, STOP 6)
     6     2    uint16   reserved, 0
     8     4    uint32   sequence number (a reply repeats its request's)
    12     8    float64  simulated time, s
    20     4    uint32   count: the number of float64 values (ERROR: of UTF-8 bytes)
    24     8*n  float64  values (ERROR: the message text)

``START`` (master -> endpoint, time = start time): values ``[h, vr_1, v_1, vr_2, v_2,
...]``: the communication step, then each parameter's value reference and value (an
Integer or Boolean as a float64). The endpoint instantiates the component, applies them,
initialises and answers ``READY`` (count 0), or ``ERROR`` with the reason. ``INPUTS``
(time ``t_k``): the component's inputs, in the order of its model description. The
endpoint first steps from the time it is at to ``t_k`` (in steps of ``h``, with the inputs
it holds), then sets these inputs and answers ``OUTPUTS``: its outputs at ``t_k``, in the
order of its model description. ``STOP``: terminate, no answer. The C onboard program
(:mod:`glider_cosim.realtime.onboard`) implements the same.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

MAGIC = b"GCSM"
VERSION = 1
HEADER = struct.Struct("<4sBBHIdI")
START, READY, INPUTS, OUTPUTS, ERROR, STOP = 1, 2, 3, 4, 5, 6
TYPES = {START: "START", READY: "READY", INPUTS: "INPUTS", OUTPUTS: "OUTPUTS", ERROR: "ERROR",
         STOP: "STOP"}  # fmt: skip
#: most values in one message (and so the largest datagram: 24 + 8 * 1024 bytes)
MAX_VALUES = 1024
MAX_SIZE = HEADER.size + 8 * MAX_VALUES


class ProtocolError(ValueError):
    """A datagram that is not a message of this format (what is wrong is said)."""


@dataclass
class Message:
    """One decoded message: ``type``, ``seq``, ``time`` (s), ``values`` or ``text``."""

    type: int
    seq: int
    time: float
    values: list[float] = field(default_factory=list)
    text: str = ""


def encode(kind: int, seq: int, time: float, values: list[float] | tuple = ()) -> bytes:
    """One message as bytes (``values`` as float64)."""
    if len(values) > MAX_VALUES:
        raise ProtocolError(f"{len(values)} values: expected at most {MAX_VALUES}")
    n = len(values)
    return HEADER.pack(MAGIC, VERSION, kind, 0, seq, time, n) + struct.pack(f"<{n}d", *values)


def encode_error(seq: int, time: float, text: str) -> bytes:
    """An ``ERROR`` message with ``text`` (UTF-8, cut to fit)."""
    raw = text.encode("utf-8", "replace")[: 8 * MAX_VALUES]
    return HEADER.pack(MAGIC, VERSION, ERROR, 0, seq, time, len(raw)) + raw


def decode(data: bytes) -> Message:
    """The message in ``data``; raises :class:`ProtocolError` naming what is wrong."""
    if len(data) > MAX_SIZE:
        raise ProtocolError(f"oversized: {len(data)} bytes, expected at most {MAX_SIZE}")
    if len(data) < HEADER.size:
        raise ProtocolError(f"malformed: {len(data)} bytes, expected a {HEADER.size}-byte header")
    magic, version, kind, _, seq, time, count = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise ProtocolError(f"malformed: magic {magic!r}, expected {MAGIC!r}")
    if version != VERSION:
        raise ProtocolError(f"wrong version: {version}, expected {VERSION}")
    if kind not in TYPES:
        raise ProtocolError(f"malformed: message type {kind}, expected 1 to {len(TYPES)}")
    body = data[HEADER.size :]
    if kind == ERROR:
        if len(body) != count:
            raise ProtocolError(f"malformed: ERROR of {len(body)} bytes, header says {count}")
        return Message(kind, seq, time, text=body.decode("utf-8", "replace"))
    if len(body) != 8 * count:
        raise ProtocolError(
            f"malformed: {len(body)} payload bytes, expected {8 * count} for {count} values"
        )
    return Message(kind, seq, time, list(struct.unpack(f"<{count}d", body)))


def parse_udp(url: str, what: str = "endpoint") -> tuple[str, int]:
    """``udp://HOST:PORT`` -> ``(host, port)``; raises ValueError naming ``what``."""
    host, sep, port = url.removeprefix("udp://").rpartition(":")
    if not url.startswith("udp://") or not sep or not host or not port.isdigit():
        raise ValueError(f"{what} {url!r} is invalid: expected udp://HOST:PORT")
    if int(port) > 65535:
        raise ValueError(f"{what} {url!r}: port {port} is invalid: expected 0 to 65535")
    return host.strip("[]"), int(port)
