"""deferred_sigint: Ctrl-C and SIGTERM become a flag during a run, and the handlers before
it are back after it, whatever happened inside."""

from __future__ import annotations

import os
import signal
import threading

import pytest

from glider_cosim.master.errors import deferred_sigint


def _handlers() -> tuple:
    return signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_is_a_flag_inside_and_the_handlers_come_back(sig):
    before = _handlers()
    with deferred_sigint() as interrupted:
        assert interrupted() == 0
        assert _handlers() != before
        os.kill(os.getpid(), sig)  # the handler runs before kill returns to Python code
        assert interrupted() == int(sig)
    assert _handlers() == before
    assert isinstance(signal.getsignal(signal.SIGTERM), signal.Handlers)  # as installed


def test_the_handlers_come_back_after_an_exception():
    def mine(signum, frame):
        pass

    old = signal.signal(signal.SIGTERM, mine)
    try:
        with pytest.raises(LookupError), deferred_sigint():
            raise LookupError("inside the run")
        assert signal.getsignal(signal.SIGTERM) is mine
    finally:
        signal.signal(signal.SIGTERM, old)


def test_outside_the_main_thread_nothing_is_installed():
    seen = []

    def body():
        with deferred_sigint() as interrupted:
            seen.append((interrupted(), _handlers()))

    before = _handlers()
    t = threading.Thread(target=body)
    t.start()
    t.join()
    assert seen == [(0, before)]
