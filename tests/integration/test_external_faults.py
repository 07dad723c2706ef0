"""Faults between the master and an endpoint, on loopback: a proxy drops, duplicates,
delays and reorders datagrams both ways and injects malformed, oversized, wrong-version
and foreign ones; the endpoint is killed in mid-run. Each is named (counted in
``metrics.json`` or said in the message); nothing crashes; nothing is written outside
``--out``; the results so far are kept."""

from __future__ import annotations

import json
import os
import select
import signal
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from realtime_helpers import Served

from glider_cosim.realtime import protocol as p
from glider_cosim.realtime.external import Endpoint
from glider_cosim.realtime.pacing import RealTime
from glider_cosim.runner import simulate

pytestmark = pytest.mark.integration


class Proxy:
    """A UDP relay on 127.0.0.1 between the master and ``target`` that breaks things:
    per direction, datagram ``n`` is dropped, sent twice, held back or swapped with the
    next, as ``faults(direction, n)`` says (``"drop"``, ``"dup"``, ``"delay"``,
    ``"swap"`` or None); after the 20th request it sends the master junk."""

    def __init__(self, target: tuple[str, int], faults, delay: float = 0.01):
        self.target, self.faults, self.delay = target, faults, delay
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.foreign = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.foreign.bind(("127.0.0.1", 0))
        self.url = f"udp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.master = None
        self.done = threading.Event()
        self.n = {"up": 0, "down": 0}
        self.later: list[tuple[float, bytes, tuple]] = []
        self.held: dict[str, tuple[bytes, tuple] | None] = {"up": None, "down": None}
        self.thread = threading.Thread(target=self._loop, daemon=True)

    def __enter__(self) -> Proxy:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.done.set()
        self.thread.join(10)
        self.sock.close()
        self.foreign.close()

    def _send(self, data: bytes, to: tuple) -> None:
        self.sock.sendto(data, to)

    def _junk(self) -> None:
        ok = p.encode(p.OUTPUTS, 1, 0.0, [0.0])
        for raw in (b"junk", b"\0" * (p.MAX_SIZE + 8), ok[:4] + b"\x07" + ok[5:]):
            self._send(raw, self.master)
        self.foreign.sendto(ok, self.master)  # from an unexpected address
        self._send(b"junk", self.target)  # and to the endpoint

    def _loop(self) -> None:
        while not self.done.is_set():
            now = time.monotonic()
            for item in [x for x in self.later if x[0] <= now]:
                self.later.remove(item)
                self._send(item[1], item[2])
            if not select.select([self.sock], [], [], 0.002)[0]:
                continue
            data, addr = self.sock.recvfrom(65536)
            way = "down" if addr == self.target else "up"
            if way == "up":
                self.master = addr
            to = self.master if way == "down" else self.target
            self.n[way] += 1
            if way == "up" and self.n["up"] == 20:
                self._junk()
            fault = self.faults(way, self.n[way])
            if fault == "drop":
                continue
            if fault == "delay":
                self.later.append((now + self.delay, data, to))
                continue
            if fault == "swap" and self.held[way] is None:
                self.held[way] = (data, to)
                continue
            self._send(data, to)
            if fault == "dup":
                self._send(data, to)
            if self.held[way] is not None:
                self._send(*self.held[way])
                self.held[way] = None


def every_fault(way: str, n: int):
    if n < 3:
        return None  # let the start through
    return {1: "drop", 3: "dup", 5: "delay", 7: "swap"}.get(n % (11 if way == "up" else 13))


def test_lockstep_through_every_fault_still_equals_the_fmu(native_dir, tmp_path):
    out = tmp_path / "out"
    with Served(native_dir / "GliderController.fmu") as srv, Proxy(srv.addr, every_fault) as px:
        ext = simulate("default", out, fmu_dir=native_dir, build=False, stop_time=2.0,
                       plots=False, external={"controller": px.url})  # fmt: skip
    ref = simulate("default", None, fmu_dir=native_dir, build=False, stop_time=2.0)
    assert ext.status == "ok" and np.array_equal(ext.data, ref.data)
    c = json.loads((out / "metrics.json").read_text())["external"]["controller"]
    assert c["malformed"] >= 3 and c["foreign"] >= 1  # junk, oversized, version; foreign
    assert c["resent"] >= 1 and c["stale"] >= 1  # drops resent; duplicates, late ones
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_real_time_holds_the_last_value_of_a_late_reply_and_counts_it(native_dir):
    def late(way, n):
        return "delay" if way == "down" and n > 2 and n % 4 == 0 else None

    with Served(native_dir / "GliderController.fmu") as srv, Proxy(srv.addr, late, 0.05) as px:
        r = simulate("default", None, fmu_dir=native_dir, build=False, stop_time=1.0,
                     real_time=RealTime(rtf=2.0), external={"controller": px.url})  # fmt: skip
    assert r.status == "ok" and len(r.data) == 51
    c = r.metrics["real_time"]["external"]["controller"]
    assert c["late_replies"] >= 5 and c["stale"] >= 1  # 10 ms deadline, 50 ms delay
    assert "late or missing replies held" in __import__(
        "glider_cosim.realtime.pacing", fromlist=["describe"]
    ).describe(r.metrics["real_time"])


def test_an_endpoint_killed_mid_run_stops_it_and_keeps_the_rows(native_dir, tmp_path):
    cli = "import sys; from glider_cosim.cli.main import console_main; console_main()"
    srv = subprocess.Popen(
        [sys.executable, "-c", cli, "serve", "controller", "--fmu",
         str(native_dir / "GliderController.fmu"), "--listen", "udp://127.0.0.1:0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        line = srv.stdout.readline()
        url = line.split()[-1]
        assert line.startswith("serving controller (") and url.startswith("udp://127.0.0.1:")
        threading.Timer(1.0, os.kill, (srv.pid, signal.SIGKILL)).start()
        out = tmp_path / "out"
        r = simulate("default", out, fmu_dir=native_dir, build=False, stop_time=20.0,
                     plots=False, real_time=RealTime(rtf=2.0),
                     external={"controller": Endpoint(url, timeout=0.5)})  # fmt: skip
    finally:
        srv.kill()
        srv.wait(10)
    assert r.status == "error"
    assert (
        r.message == f"controller ({url}): no reply for 0.5 s (--external-timeout): the run stops"
    )
    rows = (out / "results.csv").read_text().splitlines()
    m = json.loads((out / "metrics.json").read_text())
    assert m["status"] == "error" and 20 < m["rows"] == len(rows) - 1 < 1001
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
