"""The reference the tests hold today's outcome code to: the sample-by-sample loop of
the zero crossings (``glider_cosim.runner.outcome._crossings`` before issue 31, which
vectorised it), and the metrics that loop gave."""

from __future__ import annotations

import math

import numpy as np


def crossings_loop(t, e, hyst, jump=math.inf):
    """The zero crossings, sample by sample (the loop ``_crossings`` replaced)."""
    times = []
    state = 0
    last_change = None
    for i in range(len(e)):
        if i > 0 and np.sign(e[i]) != np.sign(e[i - 1]) and e[i - 1] != 0.0:
            if abs(e[i] - e[i - 1]) > jump:
                state = 0
                continue
            last_change = i
        s = 1 if e[i] > hyst else (-1 if e[i] < -hyst else 0)
        if s == 0:
            continue
        if state != 0 and s != state and last_change is not None:
            j = last_change
            a, b = e[j - 1], e[j]
            times.append(t[j - 1] + (t[j] - t[j - 1]) * a / (a - b) if a != b else t[j])
        state = s
    return np.array(times)


def glide_metrics_loop(columns, data, theta_ge, t_on, completed=True):
    """``glide_metrics`` of a run's table as the code before issue 31 computed them: the
    zero crossings by :func:`crossings_loop`, the columns as strided views of the table."""
    from glider_cosim.runner import metrics, outcome

    saved = outcome._crossings
    outcome._crossings = crossings_loop
    try:
        cols = list(columns)
        return metrics.glide_metrics(data[:, 0], data[:, cols.index("plant.theta_g")],
                                     data[:, cols.index("controller.delta_cmd")], theta_ge,
                                     t_on, completed)  # fmt: skip
    finally:
        outcome._crossings = saved
