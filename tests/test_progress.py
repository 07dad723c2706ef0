"""Progress bars: on a terminal only, never in pipes or CI (issue 21)."""

from __future__ import annotations

import io

import pytest

from glider_cosim.runner import progress


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.fixture
def no_ci(monkeypatch):
    for v in progress.CI_VARIABLES:
        monkeypatch.delenv(v, raising=False)
    monkeypatch.setenv("TERM", "xterm")


def test_only_on_a_terminal(no_ci, monkeypatch):
    assert progress.wanted(_Tty())
    assert not progress.wanted(io.StringIO())  # a pipe or a file
    assert progress.sweep_line(io.StringIO()) is None
    monkeypatch.setenv("CI", "true")
    assert not progress.wanted(_Tty())
    assert progress.sweep_line(_Tty()) is None


class _Rec:
    def __init__(self):
        self.rows, self.closed = [], False

    def start(self, columns):
        self.columns = columns

    def row(self, values):
        self.rows.append(values)

    def close(self):
        self.closed = True


def test_run_bar_after_a_while_then_cleared(no_ci, monkeypatch):
    out, inner = _Tty(), _Rec()
    monkeypatch.setattr(progress, "RUN_SHOW_AFTER_S", 0.0)
    rec = progress.RunProgress(inner, rows=256, stop_time=5.12, stream=out)
    rec.start(["time"])
    for k in range(256):
        rec.row([k * 0.02])
    rec.close()
    assert len(inner.rows) == 256 and inner.closed
    text = out.getvalue()
    assert "run: [" in text and "t = 1.3 / 5.12 s" in text and text.endswith("\r\033[K")


def test_short_run_prints_nothing(no_ci):
    out = _Tty()
    rec = progress.RunProgress(_Rec(), rows=100, stop_time=2.0, stream=out)
    rec.start(["time"])
    for k in range(100):
        rec.row([k])
    rec.close()
    assert out.getvalue() == ""


def test_sweep_line(no_ci):
    out = _Tty()
    line = progress.sweep_line(out)
    line(1, 2, 0, 1.0)
    line(2, 2, 1, 2.0)
    assert out.getvalue().endswith("2/2 done, 1 failed, 1.0 runs/s \n")
