"""Runs of the glider's closed loop: ``simulate`` (the API behind ``glider-cosim run``),
its recorders, metrics, outcome and run record (its plots are drawn by
:mod:`glider_cosim.figures`).

The public API: :func:`simulate`, :class:`RunResult`, :func:`run_ssp`, and the typed
errors raised before anything is instantiated (all ``ValueError``). Each name is imported
on first use: ``glider-cosim run`` starts its plots' process
(:mod:`glider_cosim.figures.drawing`) before the master and fmpy are imported.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..inputs.lazy import lazy_names

if TYPE_CHECKING:
    from ..inputs.ssp_files import SSPError
    from ..master.errors import SystemSpecError
    from ..scenarios.scenario import ScenarioError
    from .run import RunResult, simulate
    from .ssp import run_ssp

__all__ = ["RunResult", "SSPError", "ScenarioError", "SystemSpecError", "run_ssp", "simulate"]
__getattr__, __dir__ = lazy_names(
    __name__,
    {"RunResult": "run", "simulate": "run", "run_ssp": "ssp",
     "SSPError": "glider_cosim.inputs.ssp_files", "SystemSpecError": "glider_cosim.master.errors",
     "ScenarioError": "glider_cosim.scenarios.fields"},
)  # fmt: skip
