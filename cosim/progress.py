"""Progress on stderr for every wait over two seconds: what is being done, how far along.

One rule for every command (:func:`mode`):

- ``"bar"``: stderr is a terminal and no CI is detected (``CI``, ``GITHUB_ACTIONS``, ...
  unset, ``TERM`` not ``dumb``): a tqdm bar, redrawn in place;
- ``"lines"``: a pipe, a file, CI or a terminal that reports a size of 0x0: plain lines,
  one per step (``building GliderPlant.fmu native x86_64-linux (50 of 60)``), never
  carriage returns, so a log reads top to bottom;
- ``"off"``: ``--quiet`` (:func:`set_quiet`): nothing.

:class:`Progress` counts the steps of a task (FMU builds, ``report``, ``sweep``, the
exports); :class:`RunProgress` wraps a run's recorder and shows the simulated time
reached (``run --real-time``: the wall time against its total) once the run has taken
:data:`SHOW_AFTER_S`. While one of them is shown, a nested one stays silent (a report's
runs draw no bar of their own).
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Sequence
from typing import Any, TextIO

from tqdm import tqdm

#: environment variables that mean "running under CI": plain lines, never a bar
CI_VARIABLES = ("CI", "GITHUB_ACTIONS", "GITLAB_CI", "BUILDKITE", "JENKINS_URL", "TF_BUILD")
#: a run's progress appears only once the run has taken this long (s)
SHOW_AFTER_S = 2.0
#: plain lines: a run's line at most this often (s)
LINE_EVERY_S = 5.0
#: a bar is redrawn at most this often (s), and at least this often while a step runs
BAR_EVERY_S = 0.2
#: the most columns a bar takes
BAR_WIDTH = 100

_quiet = False
_shown = 0  # Progress and RunProgress objects showing now (nested ones stay silent)
_lock = threading.Lock()


def set_quiet(quiet: bool) -> None:
    """``--quiet``: no progress at all (True), or progress again (False)."""
    global _quiet
    _quiet = bool(quiet)


def is_quiet() -> bool:
    """True after ``set_quiet(True)``."""
    return _quiet


def in_ci() -> bool:
    """True when a CI variable is set or ``TERM`` is ``dumb``: no bar, plain lines."""
    return any(os.environ.get(v) for v in CI_VARIABLES) or os.environ.get("TERM") == "dumb"


def mode(stream: TextIO | None = None) -> str:
    """How progress is shown on ``stream`` (default ``sys.stderr``): ``"off"``
    (``--quiet``), ``"bar"`` (a terminal, no CI) or ``"lines"`` (anything else)."""
    if _quiet:
        return "off"
    stream = sys.stderr if stream is None else stream
    try:
        tty = bool(stream.isatty())
    except (AttributeError, ValueError):  # closed or not a file
        tty = False
    return "bar" if tty and not in_ci() and not _no_size(stream) else "lines"


def _no_size(stream: TextIO) -> bool:
    """True for a terminal that reports no columns (a size of 0x0: ``script(1)``, some CI
    ptys), where tqdm draws nothing: such a terminal gets plain lines."""
    try:
        return os.get_terminal_size(stream.fileno()).columns <= 0
    except (AttributeError, OSError, ValueError):  # no size to read: the bar's own default
        return False


def say(text: str, stream: TextIO | None = None) -> None:
    """One line of progress (a single wait: starting the Dask workers, drawing the plots),
    unless ``--quiet`` or a task's progress is shown already."""
    stream = sys.stderr if stream is None else stream
    if mode(stream) != "off" and not _shown:
        _write_line(stream, text)


def dask_start(workers: int, scheduler: str | None) -> str:
    """What a sweep's start waits for: ``starting 2 local Dask workers`` or ``connecting to
    the Dask scheduler at ADDR``."""
    if scheduler:
        return f"connecting to the Dask scheduler at {scheduler}"
    return f"starting {workers} local Dask worker{'s' * (workers != 1)}"


def home(path: Any) -> str:
    """A path for a progress line, with the home folder as ``~``."""
    text, root = str(path), str(os.path.expanduser("~"))
    if root not in ("", "~", os.sep) and (text == root or text.startswith(root + os.sep)):
        return "~" + text[len(root) :]
    return text


def _write_line(stream: TextIO, text: str) -> None:
    try:
        stream.write(text + "\n")
        stream.flush()
    except (OSError, ValueError):  # a closed pipe: progress is never worth a failure
        pass


def _columns(stream: TextIO) -> int:
    try:
        width = os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, OSError, ValueError):
        width = 0
    return min(width, BAR_WIDTH) if width > 0 else 80


def _new_bar(stream: TextIO, total: float, desc: str, bar_format: str, leave: bool, n: float,
             started: float, postfix: str = ""):  # fmt: skip
    """A tqdm bar at ``n`` of ``total``, its clock from ``started`` (``time.perf_counter``)."""
    bar = tqdm(total=total, desc=desc, file=stream, leave=leave, ncols=_columns(stream),
               bar_format=bar_format, postfix=postfix or None, mininterval=BAR_EVERY_S,
               dynamic_ncols=False, delay=1e-9)  # drawn below, at n  # fmt: skip
    bar.start_t -= time.perf_counter() - started  # elapsed and rate over the whole task
    bar.n = n
    bar.refresh()
    return bar


class _Ticker(threading.Thread):
    """Redraws a bar every :data:`BAR_EVERY_S` so that its clock runs during a long step
    (zig building a C runtime for minutes)."""

    def __init__(self, bar: Any, lock: threading.Lock):
        super().__init__(name="glider-cosim-progress", daemon=True)
        self.bar, self.lock, self.stop = bar, lock, threading.Event()

    def run(self) -> None:
        while not self.stop.wait(BAR_EVERY_S):
            with self.lock:
                try:
                    self.bar.refresh()
                except (OSError, ValueError):
                    return


class Progress:
    """The steps of a task on stderr: ``step(label)`` as each begins.

    Parameters
    ----------
    total : int
        Steps the task has.
    title : str
        The bar's title (``build``, ``report``, ``sweep``).
    header : str, optional
        A first line of its own, in lines mode (``building 3 native FMUs (FMI 2.0) into
        ...``); on a terminal, it is printed above the bar.
    stream : file, optional
        Where (default ``sys.stderr``).
    quiet : bool
        Show nothing, of this task and of the tasks and runs inside it.

    Use it as a context manager (or call :meth:`close`). Lines: ``label (k of total)``,
    one per step. Thread-safe: a build's pool announces its jobs from its threads.
    """

    def __init__(self, total: int, title: str, header: str | None = None,
                 stream: TextIO | None = None, quiet: bool = False):  # fmt: skip
        global _shown
        self.total, self.title = max(int(total), 1), title
        self.stream = sys.stderr if stream is None else stream
        self.done = 0
        self.t0 = time.perf_counter()
        self._lock = threading.Lock()
        self._bar: Any = None
        self._ticker: _Ticker | None = None
        with _lock:
            self.mode = "off" if _shown or quiet else mode(self.stream)
            self._counted = self.mode != "off" or quiet
            _shown += self._counted
        self._open = self.mode != "off"
        if self._open and header:
            _write_line(self.stream, header)

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close(finished=exc[0] is None)

    def step(self, label: str) -> None:
        """Step ``done + 1`` begins; ``label`` says what it does."""
        with self._lock:
            if not self._open:
                return
            self.done = min(self.done + 1, self.total)
            if self.mode == "lines":
                _write_line(self.stream, f"{label} ({self.done} of {self.total})")
                return
            self._draw(self.done - 1, label)

    def set_total(self, total: int) -> None:
        """The task has ``total`` steps (known once it has looked at what to do)."""
        with self._lock:
            self.total = max(int(total), 1)
            if self._bar is not None:
                self._bar.total = self.total

    def note(self, text: str) -> None:
        """A line of its own (above the bar on a terminal): what a long step does."""
        with self._lock:
            if not self._open:
                return
            if self._bar is not None:
                self._bar.write(text, file=self.stream)
            else:
                _write_line(self.stream, text)

    def update(self, done: int, label: str, total: int | None = None) -> None:
        """``done`` steps (of ``total``, if it changed) are finished; ``label`` says how
        it goes (a sweep's runs)."""
        with self._lock:
            if not self._open:
                return
            if total is not None and total != self.total:
                self.total = max(int(total), 1)
                if self._bar is not None:
                    self._bar.total = self.total
            self.done = min(done, self.total)
            if self.mode == "lines":
                _write_line(self.stream, label)
                return
            self._draw(self.done, label)

    def _draw(self, n: int, label: str) -> None:
        label = label.removeprefix(f"{self.title}: ")  # the bar's title says it
        if self._bar is None:
            fmt = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} [{elapsed}]{postfix}"
            self._bar = _new_bar(self.stream, self.total, self.title, fmt, True, n, self.t0, label)
            self._ticker = _Ticker(self._bar, self._lock)
            self._ticker.start()
            return
        self._bar.n = n
        self._bar.set_postfix_str(label, refresh=False)
        self._bar.refresh()

    def close(self, finished: bool = True) -> None:
        """End the task: the bar full (``finished``) and left on the screen."""
        global _shown
        with self._lock:
            opened, self._open = self._open, False
            counted, self._counted = self._counted, False
        if counted:
            with _lock:
                _shown -= 1
        if not opened:
            return
        if self._ticker is not None:
            self._ticker.stop.set()
            self._ticker.join()
        if self._bar is not None:
            if finished:
                self._bar.n = self.total
            self._bar.close()


class RunProgress:
    """A recorder that forwards to ``inner`` and shows how far the run is.

    From :data:`SHOW_AFTER_S` on: on a terminal, a bar of the simulated time reached (with
    ``real_time``: the wall time against its total), cleared when the run ends; in lines
    mode, a line every :data:`LINE_EVERY_S` and one at the end. Short runs show nothing,
    and neither does a run inside another task's progress (a report's runs).

    Parameters
    ----------
    inner : recorder
        What the rows go to.
    rows : int
        Rows the run writes (its communication points, the initial one included).
    stop_time : float
        Its stop time, s.
    real_time : float, optional
        ``run --real-time``: the run's wall time at its pace, s (``stop_time / rtf``).
    stream : file, optional
        Where (default ``sys.stderr``).
    """

    def __init__(self, inner: Any, rows: int, stop_time: float, real_time: float | None = None,
                 stream: TextIO | None = None):  # fmt: skip
        self.inner, self.rows, self.stop_time = inner, max(rows, 1), stop_time
        self.real_time = real_time
        self.stream = sys.stderr if stream is None else stream
        self.mode = "off" if _shown else mode(self.stream)
        self.n = 0
        self.t0 = time.perf_counter()
        self._next = self.t0 + SHOW_AFTER_S
        self._bar: Any = None
        self._lines = 0
        self._counted = False
        self._mask = 0 if real_time is not None else 63  # the clock read every 64 rows
        if hasattr(inner, "rows_block"):  # the C loop's blocks: found without a call
            self.rows_block = self._rows_block

    def __getattr__(self, name: str) -> Any:  # n_rows, path, ... of the inner recorder
        return getattr(self.inner, name)

    def _rows_block(self, values: Any, nrows: int, ncol: int) -> None:
        self.inner.rows_block(values, nrows, ncol)
        self.n += nrows
        if self.mode != "off" and time.perf_counter() >= self._next:
            self._show()

    def start(self, columns: Sequence[str]) -> None:
        self.inner.start(columns)

    def row(self, values: Sequence[float]) -> None:
        self.inner.row(values)
        self.n += 1
        if not self.n & self._mask and self.mode != "off" and time.perf_counter() >= self._next:
            self._show()

    def _text(self, elapsed: float, frac: float, final: bool = False) -> str:
        t = frac * self.stop_time
        if self.real_time is not None:
            return (f"run --real-time: {elapsed:.0f} s of {self.real_time:.0f} s "
                    f"(t = {t:.1f} / {self.stop_time:g} s)")  # fmt: skip
        if final:
            return f"run: t = {t:.1f} / {self.stop_time:g} s simulated in {elapsed:.0f} s"
        left = elapsed * (1 - frac) / frac if frac > 0 else 0.0
        return (f"run: t = {t:.1f} / {self.stop_time:g} s simulated, {elapsed:.0f} s elapsed, "
                f"about {left:.0f} s left")  # fmt: skip

    def _show(self) -> None:
        global _shown
        now = time.perf_counter()
        frac = min(self.n / self.rows, 1.0)
        if not self._counted:
            with _lock:
                _shown += 1
            self._counted = True
        if self.mode == "lines":
            _write_line(self.stream, self._text(now - self.t0, frac))
            self._lines += 1
            self._next = now + LINE_EVERY_S
            return
        t = frac * self.stop_time
        if self._bar is None:
            stop = f"{self.stop_time:g}".replace("{", "{{").replace("}", "}}")
            if self.real_time is not None:
                fmt = ("run --real-time: {percentage:3.0f}%|{bar}| {elapsed_s:.0f} s of "
                       f"{self.real_time:.0f} s, t = {{n:.1f}} / {stop} s")  # fmt: skip
            else:
                fmt = ("run: {percentage:3.0f}%|{bar}| t = {n:.1f} / " + stop
                       + " s [{elapsed}<{remaining}]")  # fmt: skip
            self._bar = _new_bar(self.stream, self.stop_time, "run", fmt, False, t, self.t0)
        else:
            self._bar.n = t
            self._bar.refresh()
        self._next = now + BAR_EVERY_S

    def close(self) -> None:
        global _shown
        self.inner.close()
        if self._bar is not None:
            self._bar.close()  # leave=False: the line is cleared
        elif self._lines:
            frac = min(self.n / self.rows, 1.0)
            _write_line(self.stream, self._text(time.perf_counter() - self.t0, frac, True))
        if self._counted:
            with _lock:
                _shown -= 1
            self._counted = False


def sweep_progress(stream: TextIO | None = None) -> tuple[Any, Progress]:
    """The sweep's progress callback ``(done, total, failed, seconds)`` and its
    :class:`Progress` (close it when the sweep ends): runs done, failed and runs/s."""
    bar = Progress(1, "sweep", stream=stream)

    def progress(done: int, total: int, failed: int, secs: float) -> None:
        rate = f"{done / max(secs, 1e-9):.1f} runs/s"
        if bar.mode == "lines":
            bar.update(done, f"sweep: {done} of {total} runs done, {failed} failed, {rate}", total)
        else:
            bar.update(done, f"{failed} failed, {rate}", total)

    return progress, bar
