"""Progress bars on stderr, only for a person watching a terminal.

:func:`wanted` is true when stderr is a terminal and no CI is detected (``CI``,
``GITHUB_ACTIONS``, ... set, or ``TERM=dumb``): in pipes, files and CI nothing is printed.
:class:`Progress` counts steps (``report``), :class:`RunProgress` wraps a run's recorder
(``run``: shown once the run has taken :data:`RUN_SHOW_AFTER_S`), and ``sweep`` reports
runs done, failed and runs/s through :func:`sweep_line`.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Sequence
from typing import Any, TextIO

#: environment variables that mean "running under CI": no progress output
CI_VARIABLES = ("CI", "GITHUB_ACTIONS", "GITLAB_CI", "BUILDKITE", "JENKINS_URL", "TF_BUILD")
#: a run's bar appears only once the run has taken this long (s)
RUN_SHOW_AFTER_S = 2.0


def wanted(stream: TextIO | None = None) -> bool:
    """True if progress should be drawn on ``stream`` (default ``sys.stderr``)."""
    stream = sys.stderr if stream is None else stream
    if any(os.environ.get(v) for v in CI_VARIABLES) or os.environ.get("TERM") == "dumb":
        return False
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # closed or not a file
        return False


def _bar(fraction: float, width: int) -> str:
    filled = round(width * min(max(fraction, 0.0), 1.0))
    return "#" * filled + "-" * (width - filled)


class Progress:
    """A one-line progress bar of ``total`` steps on ``stream`` (stderr)."""

    def __init__(self, total: int, stream: TextIO | None = None, width: int = 30):
        self.total, self.done, self.width = total, 0, width
        self.stream = sys.stderr if stream is None else stream
        self.t0 = time.perf_counter()

    def step(self, label: str) -> None:
        self.done += 1
        elapsed = time.perf_counter() - self.t0
        self.stream.write(f"\r[{_bar(self.done / self.total, self.width)}] {self.done}/"
                          f"{self.total} {elapsed:5.1f} s {label[:40]:40s}")  # fmt: skip
        if self.done == self.total:
            self.stream.write("\n")
        self.stream.flush()


class RunProgress:
    """A recorder that forwards to ``inner`` and draws the simulated time reached.

    Drawn at most 5 times a second, from :data:`RUN_SHOW_AFTER_S` on; the line is
    cleared when the run ends (short runs print nothing).
    """

    def __init__(self, inner: Any, rows: int, stop_time: float, stream: TextIO | None = None):
        self.inner, self.rows, self.stop_time = inner, max(rows, 1), stop_time
        self.stream = sys.stderr if stream is None else stream
        self.n = 0
        self.t0 = time.perf_counter()
        self._next = self.t0 + RUN_SHOW_AFTER_S
        self._shown = False

    def __getattr__(self, name: str) -> Any:  # n_rows, path, ... of the inner recorder
        return getattr(self.inner, name)

    def start(self, columns: Sequence[str]) -> None:
        self.inner.start(columns)

    def row(self, values: Sequence[float]) -> None:
        self.inner.row(values)
        self.n += 1
        if not self.n & 63 and time.perf_counter() >= self._next:
            self._draw()

    def _draw(self) -> None:
        now = time.perf_counter()
        frac = self.n / self.rows
        t = frac * self.stop_time
        elapsed = now - self.t0
        left = elapsed * (1 - frac) / frac if frac > 0 else 0.0
        self.stream.write(f"\rrun: [{_bar(frac, 30)}] t = {t:.1f} / {self.stop_time:g} s, "
                          f"{elapsed:.0f} s elapsed, about {left:.0f} s left ")  # fmt: skip
        self.stream.flush()
        self._shown = True
        self._next = now + 0.2

    def close(self) -> None:
        self.inner.close()
        if self._shown:
            self.stream.write("\r\033[K")
            self.stream.flush()


def sweep_line(stream: TextIO | None = None):
    """The sweep's progress callback (runs done, failed, runs/s), or None when not
    :func:`wanted`."""
    stream = sys.stderr if stream is None else stream
    if not wanted(stream):
        return None

    def progress(done: int, total: int, failed: int, secs: float) -> None:
        stream.write(f"\rsweep: [{_bar(done / max(total, 1), 30)}] {done}/{total} done, "
                     f"{failed} failed, {done / max(secs, 1e-9):.1f} runs/s ")  # fmt: skip
        if done == total:
            stream.write("\n")
        stream.flush()

    return progress
