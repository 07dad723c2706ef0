"""A run's PNG plots and ``plots.html`` drawn off the critical path (issue 31).

:func:`start_drawer` forks a child process at the start of :func:`~.run.simulate`: it
imports matplotlib and the drawing modules, loads the fonts (:func:`~.mpl.warm`) and forks
a partner (:class:`Partner`) while the co-simulation runs, then waits. When the run's
results are in, :meth:`Drawer.draw` sends them over a pipe; the child and its partner
each draw their share of the PNGs (:func:`shares`) from the plots' specs
(:func:`~.plots.build_specs`), the partner writes the page from all of them, and
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
    """The plots the drawing process draws and the ones its partner draws, the partner
    writing the page too: split about evenly by cost (:data:`COST`: a two-panel plot
    costs two one-panel ones, the page two), in :data:`~.plots.PLOTS` order within each."""
    from .plots import PLOTS

    order = [name for name, _, _ in PLOTS]
    mine: list[str] = []
    theirs: list[str] = []
    load = [0.0, COST["page"]]
    for name in sorted(order, key=lambda n: -COST.get(n, 1.0)):  # stable: PLOTS order on ties
        k = 0 if load[0] <= load[1] else 1
        (mine, theirs)[k].append(name)
        load[k] += COST.get(name, 1.0)
    return tuple(sorted(mine, key=order.index)), tuple(sorted(theirs, key=order.index))


#: what drawing each costs, in one-panel plots (measured: ``bench/draw_plots.py``, a
#: one-panel plot 6-10 ms, a two-panel one 15-19, the page 15-19); others cost 1
COST = {"pitch": 2.0, "tail_angle": 2.0, "page": 2.0}


def draw_plots(result: Any, out: Path, partner: Partner | None = None) -> dict[str, Path]:
    """Write the run's PNG plots and ``plots.html`` into ``out``; ``{name: path}`` of the
    files written. With ``partner`` (the drawing process's), this process draws the first
    of :func:`shares` and the partner the second and the page, at the same time."""
    from .plots import PLOTS, build_specs

    try:
        if partner is not None:  # it builds its share's specs, and all of them for the page
            partner.start(result, out)
            found = _draw_share(build_specs(result, out, shares()[0]), None) | partner.finish()
        else:
            specs = build_specs(result, out)
            found = _draw_share(specs, None) | _write_page(result, out, specs)
    finally:
        if partner is not None:
            partner.close()
    return {name: found[name] for name in [n for n, _, _ in PLOTS] + ["page"] if name in found}


def _write_page(result: Any, out: Path, specs: Sequence[tuple]) -> dict[str, Path]:
    """``plots.html`` of every plot's spec: ``{"page": path}``, or ``{}`` (a warning) if
    it could not be written."""
    from .pages import write_run_page

    return write_run_page(result, out, [spec for spec, _, _ in specs])


def _draw_share(specs: Sequence[tuple], names: Sequence[str] | None) -> dict[str, Path]:
    """Draw the PNGs of ``names`` (all if None) of ``specs`` (:func:`~.plots.build_specs`):
    ``{name: path}``."""
    from .mpl import draw_png

    return {path.stem: draw_png(spec, path, metadata=metadata) for spec, path, metadata in specs
            if names is None or path.stem in names}  # fmt: skip


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
    """A fork of the drawing process, made once it has imported what drawing needs (while
    the run runs): when :meth:`start` sends it the results, it draws the PNGs of the
    second of :func:`shares` and writes the page, and replies with their paths, or its
    failure in one line.
    It dies with the drawing process (``PR_SET_PDEATHSIG``) and ends when its pipe does."""

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

    def finish(self) -> dict[str, Path]:
        """Wait for the partner's PNGs: ``{name: path}``. Raises :class:`PlotError` if
        it failed or died."""
        try:
            kind, files, records = self._conn.recv()
        except (EOFError, OSError):
            _, status = os.waitpid(self.pid, 0)
            self.pid = 0
            raise PlotError(f"the second drawing process exited (status {status})") from None
        for record in records:
            logging.getLogger(record.name).handle(record)
        if kind != "ok":
            raise PlotError(files)
        return files

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
    from .plots import build_specs

    collect = _collect_logs()
    try:
        result, out = conn.recv()
    except EOFError:  # no plots after all
        return
    try:
        specs = build_specs(result, out)
        files = _draw_share(specs, shares()[1]) | _write_page(result, out, specs)
    except Exception as err:  # any failure: one line in the parent
        conn.send(("error", _failure(err), collect.records))
    else:
        conn.send(("ok", files, collect.records))


class _Collect(logging.Handler):
    """The child's log records of our modules, kept to be sent to the parent."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        record.msg, record.args, record.exc_info = record.getMessage(), None, None
        self.records.append(record)


def _end(signum: int, frame: Any) -> None:
    """SIGTERM in the drawing process: :meth:`Drawer.close` ends a child it does not
    need, which may still be importing matplotlib (1-2 s on a loaded machine): a clean
    exit (code 0; its partner dies with it), never a traceback."""
    raise SystemExit(0)


def _child(conn: Any, parents_end: Any) -> None:
    """The drawing process: prepare, wait for ``(result, out)`` (or the pipe's end),
    draw, reply ``("ok", files, records)`` or ``("error", message, records)``.
    ``parents_end``, inherited by the fork, is closed first: the parent's close is then
    the pipe's end, which an idle child reads and exits on."""
    parents_end.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    signal.signal(signal.SIGTERM, _end)
    collect = _collect_logs()
    partner: Partner | None = None
    try:
        from . import mpl, pages, plots  # noqa: F401 (imported now, while the run runs)

        mpl.warm()
        partner = Partner(close_in_partner=(conn,))
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
