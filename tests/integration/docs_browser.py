"""Headless Chromium over the DevTools protocol (``--remote-debugging-pipe``), stdlib only.

Opens a page, collects the console's errors (console.error, uncaught exceptions, failed
loads reported by the Log domain) and takes a PNG screenshot of the viewport.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path


def chromium() -> str | None:
    """The Chromium executable (Debian's ``chromium``), or None when not installed."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if found := shutil.which(name):
            return found
    return None


@dataclass
class PageVisit:
    """What one page load produced: the screenshot (PNG bytes) and the console's errors."""

    png: bytes
    errors: list[str] = field(default_factory=list)


class Browser:
    """One headless Chromium process driven over a pipe (fd 3 in, fd 4 out)."""

    def __init__(self, timeout: float = 60.0) -> None:
        exe = chromium()
        if exe is None:
            raise FileNotFoundError("chromium is not installed (apt-get install chromium)")
        self.timeout = timeout
        self._profile = tempfile.TemporaryDirectory(prefix="docs-chromium-")
        to_child_r, self._to_child = os.pipe()
        self._from_child, from_child_w = os.pipe()
        # the child reads commands from fd 3 and writes replies and events to fd 4
        self._proc = subprocess.Popen(
            [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
             "--remote-debugging-pipe", f"--user-data-dir={self._profile.name}",
             "--hide-scrollbars", "about:blank"],  # fmt: skip
            pass_fds=(3, 4),
            preexec_fn=lambda: _onto_3_and_4(to_child_r, from_child_w),
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        os.close(to_child_r)
        os.close(from_child_w)
        self._buf = b""
        self._id = 0
        self._events: list[dict] = []

    def _send(self, method: str, params: dict | None = None, session: str | None = None) -> dict:
        self._id += 1
        msg: dict = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self._to_child, json.dumps(msg).encode() + b"\0")
        want = self._id
        while True:
            reply = self._read()
            if reply.get("id") == want:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self._events.append(reply)

    def _read(self) -> dict:
        deadline = time.monotonic() + self.timeout
        while b"\0" not in self._buf:
            if time.monotonic() > deadline:
                raise TimeoutError("chromium did not answer over the DevTools pipe")
            chunk = os.read(self._from_child, 1 << 16)
            if not chunk:
                raise ConnectionError("chromium closed the DevTools pipe")
            self._buf += chunk
        raw, self._buf = self._buf.split(b"\0", 1)
        return json.loads(raw)

    def visit(
        self, url: str, width: int = 1280, height: int = 1000, settle: float = 0.3
    ) -> PageVisit:
        """Load ``url`` in a new tab, wait for its load event, screenshot and console errors."""
        target = self._send("Target.createTarget", {"url": "about:blank"})["targetId"]
        s = self._send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Page.enable", "Runtime.enable", "Log.enable"):
            self._send(domain, session=s)
        self._send("Emulation.setDeviceMetricsOverride",
                   {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False},
                   session=s)  # fmt: skip
        self._events.clear()
        self._send("Page.navigate", {"url": url}, session=s)
        deadline = time.monotonic() + self.timeout
        while not any(e.get("method") == "Page.loadEventFired" for e in self._events):
            if time.monotonic() > deadline:
                raise TimeoutError(f"{url}: no load event")
            self._events.append(self._read())
        time.sleep(settle)  # late console messages of scripts run at load (s)
        self._send("Runtime.evaluate", {"expression": "1"}, session=s)  # drains the pipe
        png = base64.b64decode(self._send("Page.captureScreenshot", {"format": "png"},
                                          session=s)["data"])  # fmt: skip
        errors = [_error(e) for e in self._events if _error(e)]
        self._send("Target.closeTarget", {"targetId": target})
        return PageVisit(png=png, errors=errors)

    def close(self) -> None:
        """End the browser and remove its profile."""
        try:
            self._send("Browser.close")
        except (OSError, RuntimeError, TimeoutError, ConnectionError):
            pass
        try:
            self._proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        os.close(self._to_child)
        os.close(self._from_child)
        self._profile.cleanup()

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _onto_3_and_4(read_end: int, write_end: int) -> None:
    # in the child, before exec: copies first, so neither end is clobbered by the other
    r, w = os.dup(read_end), os.dup(write_end)
    os.dup2(r, 3)
    os.dup2(w, 4)


def _error(event: dict) -> str | None:
    method, p = event.get("method"), event.get("params", {})
    if method == "Runtime.exceptionThrown":
        d = p.get("exceptionDetails", {})
        return "exception: " + str(d.get("exception", {}).get("description") or d.get("text"))
    if method == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
        return "console.error: " + " ".join(str(a.get("value", a.get("description")))
                                            for a in p.get("args", []))  # fmt: skip
    if method == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
        e = p["entry"]
        return f"{e.get('source')}: {e.get('text')} {e.get('url', '')}".strip()
    return None


def pixel_spread(png: bytes, out: Path | None = None) -> float:
    """Standard deviation of the screenshot's grey levels (0 for a blank page), 0..1."""
    import io

    import matplotlib.image as mpimg

    img = mpimg.imread(io.BytesIO(png), format="png")
    if out is not None:
        out.write_bytes(png)
    grey = img[..., :3].mean(axis=-1)
    return float(grey.std())
