"""Outcome detection (settled / not settled / limit cycle / diverging) on analytic signals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from outcome_reference import crossings_loop

from glider_cosim.runner.metrics import describe_outcome, glide_metrics
from glider_cosim.runner.outcome import (
    DIVERGING,
    HOLD_PERIODS,
    LIMIT_CYCLE,
    MIN_HOLD_S,
    NOT_SETTLED,
    SETTLED,
    TUMBLING,
    TrajectoryError,
    classify,
)

T = np.arange(0.0, 60.0 + 1e-9, 0.02)
W = 2 * math.pi / 1.8  # period 1.8 s, like the loop near its stability limit


def test_damped_oscillation_settles_at_the_last_exit_from_the_band():
    e = 0.2 * np.exp(-0.4 * T) * np.cos(W * T)
    o = classify(T, e, 0.004)
    assert o.status == SETTLED
    outside = np.nonzero(np.abs(e) > 0.004)[0]
    assert o.settling_time_s == pytest.approx(T[outside[-1] + 1])
    assert o.period_s == pytest.approx(1.8, rel=0.05)
    assert o.hold_required_s == pytest.approx(max(MIN_HOLD_S, HOLD_PERIODS * o.period_s))


def test_sustained_oscillation_is_a_limit_cycle_with_its_amplitude_and_period():
    e = 0.035 * np.sin(W * T + 0.3)
    o = classify(T, e, 0.004)
    assert o.status == LIMIT_CYCLE
    assert o.amplitude == pytest.approx(0.035, rel=0.01)
    assert o.period_s == pytest.approx(1.8, rel=0.01)
    assert abs(o.rate_per_s) < 1e-3
    assert o.settling_time_s is None


def test_growing_oscillation_is_diverging_with_its_growth_rate():
    e = 0.01 * np.exp(0.05 * T) * np.cos(W * T)
    o = classify(T, e, 0.004)
    assert o.status == DIVERGING
    assert o.rate_per_s == pytest.approx(0.05, rel=0.05)


def test_monotonic_growth_is_diverging():
    e = 0.01 * np.exp(0.08 * T)
    o = classify(T, e, 0.004)
    assert o.status == DIVERGING
    assert o.rate_per_s == pytest.approx(0.08, rel=0.01)


def test_an_error_that_ran_away_and_stays_far_is_diverging():
    """A tumbling glider: the angle error grew by turns and decays only locally."""
    e = np.where(T < 40.0, 0.1 + 0.08 * T, 3.3 - 0.01 * (T - 40.0))
    o = classify(T, e, 0.004)
    assert o.status == DIVERGING and o.rate_per_s < 0


def test_slow_decay_still_outside_the_band_is_not_settled():
    e = 0.2 * np.exp(-0.03 * T) * np.cos(W * T)
    o = classify(T, e, 0.004)
    assert o.status == NOT_SETTLED
    assert o.rate_per_s == pytest.approx(-0.03, rel=0.05)


def test_passing_through_the_band_at_a_zero_crossing_is_not_settling():
    """The trap seen on K_c = 6: the last samples of a sustained oscillation fall inside
    the band at a zero crossing."""
    t = T[T <= 60.0 - 0.05]
    e = 0.035 * np.sin(W * (t - t[-1]) + 0.002)  # ends just past a zero crossing
    assert np.all(np.abs(e[-2:]) < 0.004)
    o = classify(t, e, 0.004)
    assert o.status == LIMIT_CYCLE
    assert o.settling_time_s is None


def test_entering_the_band_too_late_is_not_settled():
    """A decay that enters the band less than the required hold before the end."""
    e = np.where(T < 55.0, 0.2 * np.exp(-0.01 * T), 0.2 * np.exp(-0.55) * np.exp(-2 * (T - 55)))
    o = classify(T, e, 0.004)
    assert o.status == NOT_SETTLED
    assert o.in_band_s is not None and o.in_band_s < MIN_HOLD_S


def test_long_period_needs_three_periods_in_the_band():
    """A damped slow mode (period 27 s, like the open loop) inside the band for 14 s."""
    w = 2 * math.pi / 27.0
    e = 0.22 * np.exp(-0.0916 * T) * np.cos(w * T)
    band = 0.0044
    o = classify(T, e, band)
    assert o.status == NOT_SETTLED
    assert o.hold_required_s == pytest.approx(3 * 27.0, rel=0.05)
    t2 = np.arange(0.0, 150.0 + 1e-9, 0.02)
    o2 = classify(t2, 0.22 * np.exp(-0.0916 * t2) * np.cos(w * t2), band)
    assert o2.status == SETTLED


def test_an_angle_that_keeps_turning_is_tumbling():
    o = classify(T, 0.5 * T, 0.004, period=2 * math.pi)
    assert o.status == TUMBLING
    assert o.rate_per_s == pytest.approx(0.5 / (2 * math.pi))
    assert o.period_s == pytest.approx(4 * math.pi)


def test_an_angle_that_loops_once_and_then_settles_has_settled():
    e = 2 * math.pi * (1 - np.exp(-0.5 * T)) + 0.2 * np.exp(-0.5 * T)
    assert classify(T, e, 0.004).status != SETTLED  # 360 deg away, unwrapped
    o = classify(T, e, 0.004, period=2 * math.pi)
    assert o.status == SETTLED


@pytest.mark.parametrize(
    ("t", "e", "band", "match"),
    [
        (np.arange(3.0), np.zeros(2), 0.1, "same length"),
        (np.array([0.0, 1.0, 1.0]), np.zeros(3), 0.1, "strictly increasing"),
        (np.arange(3.0), np.array([0.0, np.nan, 0.0]), 0.1, "finite"),
        (np.arange(3.0), np.zeros(3), 0.0, "band = 0.0 is invalid"),
    ],
)
def test_bad_input_is_refused(t, e, band, match):
    with pytest.raises(TrajectoryError, match=match):
        classify(t, e, band)


def test_glide_metrics_reports_the_outcome_and_stops():
    theta_ge = -0.39
    theta = theta_ge + 0.035 * np.sin(W * T + 0.3)
    cmd = np.zeros_like(T)
    m = glide_metrics(T, theta, cmd, theta_ge, 0.0)
    assert m["outcome"] == LIMIT_CYCLE and m["settling_time_s"] is None
    assert describe_outcome(m) == "limit cycle: amplitude 2.01 deg, period 1.80 s"
    m = glide_metrics(T, theta, cmd, theta_ge, 0.0, completed=False)
    assert m["outcome"] == "stopped" and m["settling_time_s"] is None


def _signals(rng, count):
    """Random error signals: noise, damped and growing waves, values on a few levels
    (zeros and exact hysteresis values included), wrapped angles."""
    for k in range(count):
        n = int(rng.integers(0, 300))
        t = np.cumsum(rng.uniform(0.001, 0.1, n))
        kind = k % 4
        if kind == 0:
            e = rng.normal(0.0, 1.0, n)
        elif kind == 1:
            e = np.sin(t * rng.uniform(0.1, 5.0)) * np.exp(-t * rng.uniform(-0.1, 0.5))
            e += rng.normal(0.0, 0.05, n)
        elif kind == 2:
            e = rng.choice([-3.0, -1.0, -0.5, 0.0, 0.3, 0.5, 1.0, 3.0], n)
        else:
            e = np.mod(np.cumsum(rng.normal(0.0, 0.7, n)) + math.pi, 2 * math.pi) - math.pi
        yield t, e, float(rng.choice([0.0, 0.3, 1.0])), float(rng.choice([math.inf, math.pi, 0.5]))


def test_crossings_are_bit_for_bit_those_of_the_loop():
    """The vectorised zero crossings: the same times, bit for bit, as the loop."""
    from glider_cosim.runner.outcome import _crossings

    for t, e, hyst, jump in _signals(np.random.default_rng(7), 2000):
        want, got = crossings_loop(t, e, hyst, jump), _crossings(t, e, hyst, jump)
        assert got.dtype == want.dtype and got.shape == want.shape, (hyst, jump, e)
        assert got.tobytes() == want.tobytes(), (hyst, jump, e)


def test_classify_does_not_loop_in_python_over_the_samples():
    """A 60 s run's classification runs a bounded number of Python lines (the zero
    crossings were a Python loop over the 3000 samples, twice)."""
    import sys

    e = 0.2 * np.exp(0.02 * T) * np.cos(W * T)  # not settled: both crossing searches run
    lines = 0

    def tracer(frame, event, arg):
        nonlocal lines
        if frame.f_code.co_filename.endswith("outcome.py"):
            lines += event == "line"
            return tracer
        return None

    sys.settrace(tracer)
    try:
        o = classify(T, e, 0.004)
    finally:
        sys.settrace(None)
    assert o.status == DIVERGING
    assert lines < 1000, f"{lines} Python lines for {len(T)} samples"
