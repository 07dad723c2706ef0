"""A run's PNG plots and ``plots.html`` drawn off the critical path (issue 31).

:func:`start_drawer` forks a child process at the start of :func:`~.run.simulate`: it
imports matplotlib, warms its fonts and makes the plots' blank figures
(:func:`~.plots.make_ahead`, until the results come) while the co-simulation runs, then
waits. When the run's results are in, :meth:`Drawer.draw` sends them over a pipe, the
child draws every PNG and the page, and :meth:`Drawer.draw` returns once they are all
written: the files
exist when ``simulate`` (and ``glider-cosim run``) returns, as before. The child ignores
Ctrl-C (the run decides: its rows are written, then the plots of the rows so far);
:meth:`Drawer.close` ends and reaps a child that is not needed or not finished, and
removes a half-written file (each PNG and the page are written beside their name and
renamed). A failure in the child is raised in the parent as :class:`PlotError`, and the
child's log records (e.g. ``plots.html not written``) are logged in the parent.

Where ``fork`` is not what the platform does (Windows, macOS), the plots are drawn in
the process, after the run (:func:`draw_plots`).
"""

from __future__ import annotations

import logging
import os
import signal
import sys
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

log = logging.getLogger(__name__)
#: the suffix of a file being written (renamed when complete)
PART = ".part"


class PlotError(OSError):
    """The PNG plots could not be written (the run's results and metrics are kept)."""


@dataclass
class PlotData:
    """What the plots read of a :class:`~.run.RunResult`, in classes the drawing process
    has imported (unpickling a ``RunResult`` there would import the master and fmpy)."""

    scenario: Any  # name and parameters
    columns: list[str]
    data: Any  # numpy array, one row per communication point
    metrics: dict[str, Any]

    @classmethod
    def of(cls, result: Any) -> PlotData:
        sc = result.scenario
        return cls(SimpleNamespace(name=sc.name, parameters=sc.parameters),
                   list(result.columns), result.data, result.metrics)  # fmt: skip

    def column(self, name: str) -> Any:
        """One column by name."""
        return self.data[:, self.columns.index(name)]


def draw_plots(result: Any, out: Path, parallel: bool = False) -> dict[str, Path]:
    """Write the run's PNG plots and ``plots.html`` into ``out``; ``{name: path}`` of the
    files written. ``parallel`` (where the process forks): the PNGs are drawn by this
    process and a fork of it, about half each, then the page is written here."""
    from .pages import write_run_page
    from .plots import build_figures, discard_ahead, save_png

    items = build_figures(result, out)
    discard_ahead()  # blank figures of plots this run has no columns for
    try:
        if parallel and len(items) > 1:
            _save_in_two(items)
        else:
            for fig, path, metadata in items:
                save_png(fig, path, metadata)
    except BaseException:
        import matplotlib.pyplot as plt

        for fig, _, _ in items:
            plt.close(fig)
        raise
    files = {path.stem: path for _, path, _ in items}
    files.update(write_run_page(result, out, [fig for fig, _, _ in items]))  # closes them
    return files


def _save_in_two(items: list[tuple[Any, Path, dict[str, str]]]) -> None:
    """Draw the PNGs in this process and a fork of it, the panels about evenly split."""
    from .plots import save_png

    mine: list = []
    theirs: list = []
    for item in sorted(items, key=lambda it: -len(it[0].get_axes())):
        lighter = mine if sum(len(f.get_axes()) for f, _, _ in mine) <= sum(
            len(f.get_axes()) for f, _, _ in theirs) else theirs  # fmt: skip
        lighter.append(item)
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the fork: its share, then its failure (if any) on the pipe
        os.close(read)
        code = 0
        try:
            for fig, path, metadata in theirs:
                save_png(fig, path, metadata)
        except BaseException as err:
            os.write(write, f"{type(err).__name__}: {err}".encode()[:4000])
            code = 1
        finally:
            os._exit(code)
    os.close(write)
    old = signal.signal(signal.SIGTERM, lambda *_: (os.kill(pid, signal.SIGKILL), os._exit(143)))
    try:
        for fig, path, metadata in mine:
            save_png(fig, path, metadata)
    finally:
        with os.fdopen(read, "rb") as pipe:
            failure = pipe.read().decode(errors="replace")
        _, status = os.waitpid(pid, 0)
        signal.signal(signal.SIGTERM, old)
    if failure or status:
        raise PlotError(failure or f"the second drawing process exited (status {status})")


class _Collect(logging.Handler):
    """The child's log records of our modules, kept to be sent to the parent."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        record.msg, record.args, record.exc_info = record.getMessage(), None, None
        self.records.append(record)


def _child(conn: Any, parents_end: Any) -> None:
    """The drawing process: prepare, wait for ``(result, out)`` (or the pipe's end),
    draw, reply ``("ok", files, records)`` or ``("error", message, records)``.
    ``parents_end``, inherited by the fork, is closed first: the parent's close is then
    the pipe's end, which an idle child reads and exits on."""
    parents_end.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    ours = logging.getLogger("glider_cosim")
    collect = _Collect()
    ours.handlers, ours.propagate = [collect], False
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from . import pages, plots  # noqa: F401 (pages: imported now, while the run runs)

        fig = plt.figure(figsize=(1, 1))  # loads the fonts
        fig.text(0.5, 0.5, "0.5 [deg]")
        fig.canvas.draw()
        plt.close(fig)
        for kind in plots.FIGURE_KINDS:  # the blank figures, until the results come
            if conn.poll():
                break
            plots.make_ahead(kind)
    except Exception:  # noqa: S110 - drawn again below, where the error is reported
        pass
    try:
        job = conn.recv()
    except EOFError:  # the run needs no plots (it failed, or was refused)
        return
    try:
        files = draw_plots(*job, parallel=True)
    except Exception as err:  # any failure: one line in the parent, not a traceback here
        from ..inputs.text import one_line

        conn.send(("error", one_line(f"{type(err).__name__}: {err}"), collect.records))
    else:
        conn.send(("ok", files, collect.records))


class Drawer:
    """A forked drawing process (:func:`start_drawer`)."""

    def __init__(self) -> None:
        import multiprocessing

        ctx = multiprocessing.get_context("fork")
        self._conn, child_conn = ctx.Pipe()
        self._process = ctx.Process(target=_child, args=(child_conn, self._conn), daemon=True,
                                    name="glider-cosim-plots")  # fmt: skip
        self._process.start()
        child_conn.close()
        self._out: Path | None = None

    def draw(self, result: Any, out: Path) -> dict[str, Path]:
        """Draw ``result``'s plots into ``out`` in the child; return when every file is
        written (``{name: path}``). Raises :class:`PlotError` if the child failed."""
        self._out = Path(out)
        try:
            self._conn.send((PlotData.of(result), self._out))
            reply = self._conn.recv()
        except (EOFError, BrokenPipeError, ConnectionResetError):
            self._process.join(5.0)
            code = self._process.exitcode
            how = f"signal {-code}" if code is not None and code < 0 else f"code {code}"
            reply = ("error", f"the drawing process exited ({how})", [])
        kind, value, records = reply
        for record in records:
            logging.getLogger(record.name).handle(record)
        self.close()
        if kind != "ok":
            raise PlotError(f"PNG plots not written ({value}); the run's results and "
                            "metrics.json are kept")  # fmt: skip
        return value

    def close(self) -> None:
        """End the child (done, not needed or interrupted), reap it and remove a file it
        left half-written."""
        self._conn.close()  # an idle child reads the end of the pipe and exits
        self._process.join(2.0)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join(2.0)
            if self._process.is_alive():
                self._process.kill()
                self._process.join()
        if self._out is not None:
            for part in self._out.glob(f"*{PART}"):
                if part.name.endswith((f".png{PART}", f".html{PART}")) and not part.is_dir():
                    part.unlink(missing_ok=True)


_PRESTARTED: list[Drawer] = []  # started by prestart(), taken by start_drawer()


def prestart() -> None:
    """Start the drawing process now, before the master and fmpy are imported (the
    command line, for ``run`` with plots): the next :func:`start_drawer` takes it."""
    if not _PRESTARTED and (drawer := _new_drawer()) is not None:
        _PRESTARTED.append(drawer)


def discard_prestarted() -> None:
    """End a drawing process :func:`prestart` started that no run took."""
    while _PRESTARTED:
        _PRESTARTED.pop().close()


def start_drawer() -> Drawer | None:
    """A :class:`Drawer` preparing in a forked child (the one :func:`prestart` started,
    if any), or None where the platform does not fork (then :func:`draw_plots` draws in
    the process)."""
    return _PRESTARTED.pop() if _PRESTARTED else _new_drawer()


def _new_drawer() -> Drawer | None:
    if not sys.platform.startswith("linux"):
        return None
    try:
        return Drawer()
    except OSError as err:  # no process to spare: draw in the process
        log.debug("plots drawn in the process: %s", err)
        return None
