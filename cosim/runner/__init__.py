"""Runs of the glider's closed loop: ``simulate`` (the API behind ``glider-cosim run``),
its recorders, metrics, outcome and run record (its plots are drawn by
:mod:`glider_cosim.figures`).

The public API: :func:`simulate`, :class:`RunResult`, :func:`run_ssp`, and the typed
errors raised before anything is instantiated (all ``ValueError``).
"""

from ..inputs.ssp_files import SSPError
from ..master.errors import SystemSpecError
from ..scenarios.fields import ScenarioError
from .run import RunResult, simulate
from .ssp import run_ssp

__all__ = ["RunResult", "SSPError", "ScenarioError", "SystemSpecError", "run_ssp", "simulate"]
