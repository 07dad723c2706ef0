"""Run an SSP with libcosim (libcosimpy), in this process or in a child process."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..inputs.ssp_files import SSPError
from .ssp_import import load_ssp


# --------------------------------------------------------------------------- libcosim
@dataclass
class LibcosimRun:
    """Rows of a libcosim run: ``columns`` (``time`` first), ``data`` (one row per
    communication point, t0 included) and the wall time per macro step (s)."""

    columns: list[str]
    data: np.ndarray
    seconds_per_step: float

    def column(self, name: str) -> np.ndarray:
        """One column by name."""
        return self.data[:, self.columns.index(name)]


class LibcosimError(RuntimeError):
    """libcosim failed to load or run an SSP (its process died or a step failed)."""


def simulate_libcosim(
    path: str | Path, variables: Sequence[str], stop_time: float | None = None
) -> LibcosimRun:
    """Run an SSP in libcosim (libcosimpy, fixed-step algorithm) in this process.

    Real variables are recorded with libcosim's time-series observer at every
    communication point, the initial one included. An FMU exception during libcosim's
    initialisation aborts the process (uncatchable): use
    :func:`simulate_libcosim_isolated` unless the SSP is known to be good.

    Parameters
    ----------
    path : path
        ``.ssp`` archive, ``.ssd`` file or folder (checked with :func:`load_ssp` first).
    variables : sequence of str
        ``instance.variable`` names of Real variables to record.
    stop_time : float, optional
        End of the run (s); default the SSP's stop time.

    Returns
    -------
    LibcosimRun
        The rows and the wall time per macro step.

    Raises
    ------
    SSPError
        The SSP is malformed or a variable is unknown.
    LibcosimError
        libcosim could not create the execution or a step failed.
    """
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    system, step, stop = load_ssp(path)
    stop = stop if stop_time is None else float(stop_time)
    n = round(stop / step)
    log_output_level(CosimLogLevel.ERROR)
    try:
        ex = CosimExecution.from_ssp_file(str(path))
    except AssertionError:  # libcosimpy asserts on a null execution
        raise LibcosimError(f"{path}: libcosim could not create an execution from it") from None
    observer = CosimObserver.create_time_series()
    ex.add_observer(observer)
    refs = []
    for name in variables:
        inst, _, var = name.partition(".")
        if inst not in system.fmus:
            raise SSPError(f"{path}: variable '{name}': no component '{inst}'")
        idx = ex.slave_index_from_instance_name(inst)
        vr = next((v.reference for v in ex.slave_variables(idx) if v.name.decode() == var), None)
        if vr is None:
            raise SSPError(f"{path}: variable '{name}': '{inst}' has no variable '{var}'")
        observer.start_time_series(idx, vr, CosimVariableType.REAL)
        refs.append((idx, vr))
    t0 = time.perf_counter()
    if not ex.step(n):
        raise LibcosimError(f"{path}: libcosim's step failed before t = {stop:g} s")
    seconds = (time.perf_counter() - t0) / max(n, 1)
    columns = ["time", *variables]
    data = np.empty((n + 1, len(columns)))
    data[:, 0] = np.arange(n + 1) * step
    for j, (idx, vr) in enumerate(refs, start=1):
        # libcosimpy 0.0.6 returns at most (last step - from_step) samples per call: the
        # last one comes with a second call
        steps: list[int] = []
        for _ in range(3):
            if len(steps) == n + 1:
                break
            times, got, values = observer.time_series_real_samples(
                idx, vr, len(steps), n + 1 - len(steps)
            )
            for k, t_ns, value in zip(got, times, values):
                data[k, 0], data[k, j] = t_ns * 1e-9, value
            steps += list(got)
        if steps != list(range(n + 1)):
            raise LibcosimError(f"{path}: libcosim recorded {len(steps)} of {n + 1} samples")
    return LibcosimRun(columns, data, seconds)


def simulate_libcosim_isolated(
    path: str | Path,
    variables: Sequence[str],
    stop_time: float | None = None,
    timeout: float = 600.0,
) -> LibcosimRun:
    """:func:`simulate_libcosim` in a subprocess (libcosim may abort or crash its process).

    Parameters
    ----------
    path, variables, stop_time
        As :func:`simulate_libcosim`.
    timeout : float
        Seconds before the subprocess is killed.

    Returns
    -------
    LibcosimRun
        The rows and the wall time per macro step.

    Raises
    ------
    SSPError
        The SSP is malformed (checked in this process first).
    LibcosimError
        The subprocess failed, died or timed out (its last message is included).
    """
    load_ssp(path)
    args = [str(path), json.dumps(list(variables)), json.dumps(stop_time)]
    try:
        p = subprocess.run(
            [sys.executable, "-m", "glider_cosim.interop.libcosim", *args],
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        raise LibcosimError(f"{path}: libcosim did not finish within {timeout:g} s") from None
    lines = p.stdout.strip().splitlines()
    if p.returncode != 0 or not lines:
        last = (p.stderr.strip().splitlines() or [f"exit code {p.returncode}"])[-1]
        raise LibcosimError(f"{path}: libcosim failed (exit code {p.returncode}): {last}")
    result = json.loads(lines[-1])
    return LibcosimRun(result["columns"], np.array(result["data"]), result["seconds_per_step"])


def _main(argv: Sequence[str]) -> int:
    """Subprocess entry of :func:`simulate_libcosim_isolated` (JSON on stdout)."""
    path, variables, stop_time = argv[0], json.loads(argv[1]), json.loads(argv[2])
    try:
        run = simulate_libcosim(path, variables, stop_time)
    except (SSPError, LibcosimError) as err:
        print(err, file=sys.stderr)
        return 1
    out = {
        "columns": run.columns,
        "data": run.data.tolist(),
        "seconds_per_step": run.seconds_per_step,
    }
    print(json.dumps(out))
    return 0


if __name__ == "__main__":  # pragma: no cover - run by simulate_libcosim_isolated
    sys.exit(_main(sys.argv[1:]))
