"""Runs of the glider's closed loop: ``simulate`` (the API behind ``glider-cosim run``),
its recorders, metrics, outcome, plots and run record.

The public API: :func:`simulate`, :class:`RunResult`, :func:`run_ssp`, and the typed
errors raised before anything is instantiated (all ``ValueError``).
"""

from glider_cosim.inputs.ssp_files import SSPError
from glider_cosim.master.errors import SystemSpecError
from glider_cosim.runner.run import RunResult, simulate
from glider_cosim.runner.ssp import run_ssp
from glider_cosim.scenarios.scenario import ScenarioError

__all__ = ["RunResult", "SSPError", "ScenarioError", "SystemSpecError", "run_ssp", "simulate"]
