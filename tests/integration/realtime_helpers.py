"""Endpoints for the real-time tests: ``glider-cosim serve`` in a thread, on port 0."""

from __future__ import annotations

import threading
from pathlib import Path

from glider_cosim.realtime.serve import serve


class Served:
    """``serve(fmu)`` on 127.0.0.1, an ephemeral port, in a daemon thread (a context)."""

    def __init__(self, fmu: Path):
        self.fmu, self.done = fmu, threading.Event()
        self.bound = threading.Event()
        self.addr: tuple[str, int] = ("", 0)

    def __enter__(self) -> Served:
        def ready(addr):
            self.addr = addr
            self.bound.set()

        self.thread = threading.Thread(
            target=serve, args=(self.fmu, "udp://127.0.0.1:0"),
            kwargs={"ready": ready, "stop": self.done.is_set}, daemon=True,
        )  # fmt: skip
        self.thread.start()
        assert self.bound.wait(30)
        return self

    @property
    def url(self) -> str:
        return f"udp://127.0.0.1:{self.addr[1]}"

    def __exit__(self, *exc) -> None:
        self.done.set()
        self.thread.join(10)
