"""The pacer of real-time runs: deadlines, lateness, overruns, the lateness limit."""

from __future__ import annotations

import time

import pytest

from glider_cosim.master.errors import SystemSpecError
from glider_cosim.realtime.pacing import Pacer, RealTime, TooLate, describe


def test_points_start_on_their_deadlines_and_an_overrun_is_counted():
    p = Pacer(0.02, RealTime(rtf=2.0))  # a point every 10 ms of wall clock
    p.start()
    t0 = time.monotonic()
    for k in range(5):
        p.wait(k)
        if k == 2:
            time.sleep(0.025)  # this step's work ends after the next deadline
        p.done(k)
    p.wait(5)
    assert time.monotonic() - t0 >= 0.05 - 1e-3
    rt = p.summary()
    assert rt["overruns"] >= 1 and rt["points"] == 6
    # never faster than the target (a busy machine may make it slower: no lower bound)
    assert rt["rtf_target"] == 2.0 and 0.0 < rt["rtf_achieved"] <= 2.01
    assert rt["lateness_ms"]["max"] >= 0.0
    assert "overruns" in describe(rt) and "target 2" in describe(rt)


def test_a_point_later_than_the_limit_stops_with_a_named_error():
    p = Pacer(0.02, RealTime(rtf=1.0, max_lateness_ms=1.0))
    p.start()
    p.wait(0)
    time.sleep(0.03)
    with pytest.raises(TooLate, match=r"t = 0.02 s started .* ms late, more than --max-late"):
        p.wait(1)


@pytest.mark.parametrize(("kw", "text"), [
    ({"rtf": 0.0}, "rtf 0.0 is invalid"),
    ({"rtf": float("inf")}, "rtf inf is invalid"),
    ({"max_lateness_ms": -1.0}, "max_lateness_ms -1.0 is invalid"),
    ({"spin_ms": -0.5}, r"spin_ms -0.5 is invalid: expected a finite number >= 0 \(ms\)"),
    ({"spin_ms": float("nan")}, "spin_ms nan is invalid"),
])  # fmt: skip
def test_bad_settings_are_refused(kw, text):
    with pytest.raises(SystemSpecError, match=text):
        RealTime(**kw)


def test_a_spin_of_a_period_never_sleeps_and_the_default_sleeps(monkeypatch):
    slept: list[float] = []
    real_sleep = time.sleep
    monkeypatch.setattr(time, "sleep", lambda s: slept.append(s) or real_sleep(s))
    p = Pacer(0.02, RealTime(rtf=2.0, spin_ms=10.0))  # a point every 10 ms, all spun
    p.start()
    for k in range(4):
        p.wait(k)
    assert slept == [] and p.summary()["spin_ms"] == 10.0
    p = Pacer(0.02, RealTime(rtf=2.0))
    p.start()
    for k in range(4):
        p.wait(k)
    assert len(slept) == 3 and all(0.0 < s <= 0.0085 + 1e-9 for s in slept), slept
    assert p.summary()["spin_ms"] == 1.5
