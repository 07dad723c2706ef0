"""Run an SSP with our master (``glider-cosim run FILE.ssp``)."""

from __future__ import annotations

from pathlib import Path

from ..inputs.ssp_files import SSD_NAME
from .run import RunResult, simulate


def run_ssp(
    path: str | Path,
    out: str | Path | None = None,
    coupling: str = "gauss-seidel",
    *,
    step: float | None = None,
    stop_time: float | None = None,
    plots: bool = True,
) -> RunResult:
    """Run an SSP with our master (``glider-cosim run FILE.ssp``).

    Parameters
    ----------
    path : path
        ``.ssp`` archive, ``.ssd`` file or folder holding ``SystemStructure.ssd``.
    out : path, optional
        Results folder (``results.csv``, ``metrics.json``, plots); None keeps the rows in
        memory.
    coupling : str
        ``"gauss-seidel"`` or ``"jacobi"`` (SSP 1.0 has no coupling scheme; libcosim's
        fixed-step algorithm is ``"jacobi"``).
    step : float, optional
        The communication step (s): overrides the SSP's (an OSP or OMSimulator
        annotation, or the FMUs' ``DefaultExperiment stepSize``); needed when it has none.
    stop_time : float, optional
        Overrides ``ssd:DefaultExperiment stopTime`` (s); needed when it has none.
    plots : bool
        Write PNG plots (with ``out``).

    Returns
    -------
    glider_cosim.runner.RunResult
        As :func:`glider_cosim.runner.simulate`, with the step and stop time of the SSP.

    Raises
    ------
    SSPError
        The SSP is malformed, or gives no step or stop time and none is passed
        (``simulate`` reads it, every check before any FMU is
        instantiated).
    """
    p = Path(path)
    if p.is_dir():
        p = p / SSD_NAME
    return simulate(
        p, out, coupling=coupling, step=step, stop_time=stop_time, plots=plots, build=False
    )
