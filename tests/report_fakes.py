"""Runs made up for the report's figures: what a :class:`RunResult` offers its plots
(columns, status, metrics, scenario), with no FMU run."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from glider_cosim.studies.figures import DEG

THETA_E = -22.5 / DEG


class FakeRun:
    """``cols``: column name -> values; ``t``: their times [s] (default 0..10 s)."""

    def __init__(self, cols: dict, status="ok", metrics=None, message="", feedback="full",
                 t=None):  # fmt: skip
        n = len(next(iter(cols.values())))
        t = np.linspace(0, 10, 501)[:n] if t is None else np.asarray(t, dtype=float)
        self.columns = ["time", *cols]
        self.data = np.column_stack([t, *cols.values()])
        self.status, self.message = status, message
        self.metrics = {"theta_ge_rad": THETA_E, "events": [], "outcome": "settled",
                        "settling_time_s": 5.0, **(metrics or {})}  # fmt: skip
        self.scenario = SimpleNamespace(name="fake", feedback=feedback, connections={},
                                        parameters={"controller": {}, "plant": {}})  # fmt: skip

    def column(self, name):
        return self.data[:, self.columns.index(name)]
