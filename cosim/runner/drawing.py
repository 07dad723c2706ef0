"""A run's PNG plots and ``plots.html`` drawn off the critical path (issue 31).

:func:`start_drawer` forks a child process at the start of :func:`~.run.simulate`: it
imports matplotlib, warms its fonts, forks a partner (:class:`Partner`) and, with it,
makes the plots' blank figures (:func:`~.plots.make_ahead`, until the results come)
while the co-simulation runs, then waits. When the run's results are in,
:meth:`Drawer.draw` sends them over a pipe; the child and its partner each build and
draw their share of the PNGs (:func:`shares`), the child writes the page, and
:meth:`Drawer.draw` returns once they are all written: the files
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

import functools
import logging
import os
import signal
import sys
from collections.abc import Sequence
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


@functools.cache
def shares() -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The plots the drawing process draws and the ones its partner draws: split in two
    about evenly by panels (a two-panel figure counts two), the larger first, in
    :data:`~.plots.PLOTS` order within each (computed when first needed: matplotlib is
    imported only where plots are drawn)."""
    from .plots import PLOTS

    mine: list[str] = []
    theirs: list[str] = []
    panels = {name: 2 if kind == "pair" else 1 for name, kind, _, _ in PLOTS}
    for name in sorted(panels, key=lambda n: -panels[n]):  # stable: PLOTS order on ties
        lighter = mine if sum(map(panels.get, mine)) <= sum(map(panels.get, theirs)) else theirs
        lighter.append(name)
    order = list(panels)
    return tuple(sorted(mine, key=order.index)), tuple(sorted(theirs, key=order.index))


def draw_plots(result: Any, out: Path, partner: Partner | None = None) -> dict[str, Path]:
    """Write the run's PNG plots and ``plots.html`` into ``out``; ``{name: path}`` of the
    files written. With ``partner`` (the drawing process's), this process draws the first
    of :func:`shares` and the partner the second, at the same time; the page is written
    here, from both."""
    import matplotlib.pyplot as plt

    from .pages import page_not_written, write_run_page
    from .plots import PLOTS

    items: list = []
    try:
        if partner is not None:
            partner.start(result, out)
        items = _draw_share(result, out, shares()[0] if partner is not None else None)
        try:
            theirs, their_specs = partner.finish() if partner is not None else ({}, {})
        except BaseException:
            for fig, _, _ in items:
                plt.close(fig)
            raise
    finally:
        if partner is not None:
            partner.close()
    found = {path.stem: path for _, path, _ in items} | theirs
    files = {name: found[name] for name, _, _, _ in PLOTS if name in found}
    if isinstance(their_specs, str):  # the partner could not describe its figures
        for fig, _, _ in items:
            plt.close(fig)
        page_not_written(their_specs)
        return files
    figures = {path.stem: fig for fig, path, _ in items} | their_specs
    shown = [figures[name] for name, _, _, _ in PLOTS if name in figures]
    files.update(write_run_page(result, out, shown))  # closes this process's figures
    return files


def _draw_share(result: Any, out: Path, names: Sequence[str] | None) -> list:
    """Build and draw the PNGs of ``names`` (all if None): their ``(figure, path,
    metadata)``, the figures left open (closed if one fails)."""
    import matplotlib.pyplot as plt

    from .plots import build_figures, discard_ahead, save_png

    items = build_figures(result, out, names)
    discard_ahead()  # blank figures of plots this run has no columns for
    try:
        for fig, path, metadata in items:
            save_png(fig, path, metadata)
    except BaseException:
        for fig, _, _ in items:
            plt.close(fig)
        raise
    return items


def _make_ahead_until(conn: Any, names: Sequence[str]) -> None:
    """The blank figures of ``names``, until something (or the end) waits on ``conn``."""
    from .plots import FIGURE_KIND, make_ahead

    for name in names:
        if conn.poll():
            break
        make_ahead(FIGURE_KIND[name])


def _collect_logs() -> _Collect:
    """Our modules' log records kept in this (forked) process, to be sent to its parent."""
    ours = logging.getLogger("glider_cosim")
    collect = _Collect()
    ours.handlers, ours.propagate = [collect], False
    return collect


def _failure(err: BaseException) -> str:
    """A drawing process's failure in one line, for its parent."""
    from ..inputs.text import one_line

    return one_line(f"{type(err).__name__}: {err}")


class Partner:
    """A fork of the drawing process, made once it has imported matplotlib (while the
    run runs): it makes the blank figures of the second of :func:`shares`, then, when
    :meth:`start` sends it the results, builds and draws those PNGs, and replies with
    their paths and page specs (:func:`~.pages.run_page_spec`), or its failure in one
    line. It dies with the drawing process (``PR_SET_PDEATHSIG``) and ends when its
    pipe does."""

    def __init__(self, close_in_partner: Sequence[Any] = ()) -> None:
        import multiprocessing

        self._conn, theirs = multiprocessing.Pipe()
        parent = os.getpid()
        self.pid = os.fork()
        if self.pid == 0:  # the partner
            code = 0
            try:
                self._conn.close()
                for conn in close_in_partner:  # the main process's pipe: its end is the child's
                    conn.close()
                _die_with(parent)
                _partner(theirs)
            except BaseException:  # noqa: BLE001 - reported on the pipe where it can be
                code = 1
            finally:
                os._exit(code)
        theirs.close()

    def start(self, result: Any, out: Path) -> None:
        """Send the results: the partner draws its share."""
        self._conn.send((result, out))

    def finish(self) -> tuple[dict[str, Path], dict[str, Any] | str]:
        """Wait for the partner's PNGs: ``({name: path}, {name: page spec})`` (the
        specs: the failure's text if it could not make them). Raises
        :class:`PlotError` if it failed or died."""
        try:
            kind, files, specs, records = self._conn.recv()
        except (EOFError, OSError):
            _, status = os.waitpid(self.pid, 0)
            self.pid = 0
            raise PlotError(f"the second drawing process exited (status {status})") from None
        for record in records:
            logging.getLogger(record.name).handle(record)
        if kind != "ok":
            raise PlotError(files)
        return files, specs

    def close(self) -> None:
        """End the partner (done, or not needed) and reap it."""
        self._conn.close()  # an idle partner reads the end of the pipe and exits
        if self.pid:
            try:
                pid, _ = os.waitpid(self.pid, os.WNOHANG)
                if pid == 0:
                    os.kill(self.pid, signal.SIGKILL)
                    os.waitpid(self.pid, 0)
            except ChildProcessError:
                pass
            self.pid = 0


def _die_with(parent: int) -> None:
    """Have the kernel kill this process when its parent dies (Linux), and exit now if
    it already has."""
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    if os.getppid() != parent:
        os._exit(0)


def _partner(conn: Any) -> None:
    """The partner's work (:class:`Partner`)."""
    from .pages import run_page_spec

    collect = _collect_logs()
    _make_ahead_until(conn, shares()[1])
    try:
        result, out = conn.recv()
    except EOFError:  # no plots after all
        return
    try:
        items = _draw_share(result, out, shares()[1])
        files = {path.stem: path for _, path, _ in items}
        try:
            specs: dict[str, Any] | str = {p.stem: run_page_spec(f) for f, p, _ in items}
        except (ValueError, TypeError, ImportError, OSError) as err:  # PageError: ValueError
            specs = str(err)
    except Exception as err:  # any failure: one line in the parent
        conn.send(("error", _failure(err), {}, collect.records))
    else:
        conn.send(("ok", files, specs, collect.records))


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
    collect = _collect_logs()
    partner: Partner | None = None
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from . import pages, plots  # noqa: F401 (pages: imported now, while the run runs)

        fig = plt.figure(figsize=(1, 1))  # loads the fonts
        fig.text(0.5, 0.5, "0.5 [deg]")
        fig.canvas.draw()
        plt.close(fig)
        partner = Partner(close_in_partner=(conn,))
        _make_ahead_until(conn, shares()[0])  # the blank figures, until the results come
    except Exception:  # noqa: S110 - drawn again below, where the error is reported
        pass
    try:
        job = conn.recv()
    except EOFError:  # the run needs no plots (it failed, or was refused)
        if partner is not None:
            partner.close()
        return
    try:
        files = draw_plots(*job, partner=partner)
    except Exception as err:  # any failure: one line in the parent, not a traceback here
        conn.send(("error", _failure(err), collect.records))
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
