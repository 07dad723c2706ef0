"""The observer's sampling rate follows the communication step unless a scenario sets it."""

from __future__ import annotations

import math
import warnings
from typing import Any

from glider_observer.filter import DEFAULT_F_CUTOFF

from .fields import ScenarioError
from .scenario import Scenario


class SamplingMismatchWarning(UserWarning):
    """The observer's ``f_sample`` is set explicitly and differs from 1 / step."""


def with_sampling(
    parameters: dict[str, dict[str, Any]],
    step: float,
    source: str = "<scenario>",
    observer: bool = True,
) -> dict[str, dict[str, Any]]:
    """The parameters with the sampled parts following the communication step.

    The observer's pre-filter runs once per communication step, so its sampling
    frequency ``observer.f_sample`` (and with it the Butterworth coefficients) is set to
    ``1 / step`` unless ``parameters`` set it explicitly. An explicit value that differs
    from ``1 / step`` (relative difference above 1e-9) is kept and warned about in one
    line (:class:`SamplingMismatchWarning`).

    Parameters
    ----------
    parameters : dict
        ``{instance: {name: value}}`` (not modified).
    step : float
        Communication step, s, > 0.
    source : str
        Named in the warning (the scenario file).
    observer : bool
        Whether the system has our observer FMU (:func:`has_our_observer`; nothing to do
        otherwise: a swapped-in observer may have no ``f_sample``).

    Returns
    -------
    dict
        A copy of ``parameters``, with ``observer.f_sample`` [Hz] filled in.

    Raises
    ------
    ScenarioError
        If ``step`` is not > 0, or the pre-filter (enabled) would sample at or below
        twice its cut-off frequency.
    """
    if not (math.isfinite(step) and step > 0):
        raise ScenarioError(f"{source}: step = {step!r} is invalid: expected a number > 0 s")
    out = {k: dict(v) for k, v in parameters.items()}
    if not observer:
        return out
    obs = out.setdefault("observer", {})
    if "f_sample" not in obs:
        obs["f_sample"] = 1.0 / step
        f_cut = float(obs.get("f_cutoff", DEFAULT_F_CUTOFF))
        if obs.get("filter_enabled", True) and not f_cut < 0.5 * obs["f_sample"]:
            raise ScenarioError(
                f"{source}: step {step:g} s samples the observer's pre-filter at "
                f"{obs['f_sample']:g} Hz, too slow for its cut-off f_cutoff = {f_cut:g} Hz: "
                f"expected observer.f_cutoff below {0.5 * obs['f_sample']:g} Hz (or "
                "observer.filter_enabled = false)"
            )
    elif abs(float(obs["f_sample"]) * step - 1.0) > 1e-9:
        warnings.warn(
            f"{source}: observer.f_sample = {float(obs['f_sample']):g} Hz differs from the "
            f"communication rate 1/step = {1.0 / step:g} Hz (the pre-filter is designed for "
            "the former and runs at the latter)",
            SamplingMismatchWarning,
            stacklevel=2,
        )
    return out


def has_our_observer(sc: Scenario) -> bool:
    """The scenario runs our GliderObserver FMU (not none, not a swapped-in one)."""
    return sc.observer and "observer" not in sc.fmus
