"""The endpoint message format: round trips and every refusal named."""

from __future__ import annotations

import struct

import pytest

from glider_cosim.realtime import protocol as p


def test_a_message_round_trips_little_endian():
    raw = p.encode(p.INPUTS, 7, 0.25, [1.5, -2.0])
    assert raw[:4] == b"GCSM" and raw[4] == 1 and raw[5] == p.INPUTS
    assert struct.unpack_from("<I", raw, 8)[0] == 7 and len(raw) == 24 + 16
    m = p.decode(raw)
    assert (m.type, m.seq, m.time, m.values) == (p.INPUTS, 7, 0.25, [1.5, -2.0])
    e = p.decode(p.encode_error(3, 1.0, "refused: K_c"))
    assert (e.type, e.seq, e.text) == (p.ERROR, 3, "refused: K_c")


@pytest.mark.parametrize(("raw", "text"), [
    (b"GCSM", "malformed: 4 bytes, expected a 24-byte header"),
    (b"XXXX" + p.encode(p.READY, 1, 0.0)[4:], "malformed: magic b'XXXX'"),
    (p.encode(p.READY, 1, 0.0)[:4] + b"\x02" + p.encode(p.READY, 1, 0.0)[5:],
     "wrong version: 2, expected 1"),
    (p.encode(p.INPUTS, 1, 0.0, [1.0])[:-1], "malformed: 7 payload bytes, expected 8"),
    (p.encode(p.READY, 1, 0.0)[:5] + b"\x09" + p.encode(p.READY, 1, 0.0)[6:],
     "malformed: message type 9"),
    (b"\0" * (p.MAX_SIZE + 1), "oversized: 8217 bytes"),
])  # fmt: skip
def test_a_bad_datagram_is_refused_by_name(raw, text):
    with pytest.raises(p.ProtocolError, match=text.replace("(", r"\(")):
        p.decode(raw)


@pytest.mark.parametrize(
    "url", ["tcp://127.0.0.1:1", "udp://127.0.0.1", "udp://:9", "udp://h:99999"]
)
def test_a_bad_address_is_refused(url):
    with pytest.raises(ValueError, match="invalid"):
        p.parse_udp(url)
