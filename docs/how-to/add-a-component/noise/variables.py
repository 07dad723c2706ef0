"""The noise block's FMU variables in value-reference order (:class:`glider_fmi.variables.Var`):
read by the slave, and without pythonfmu by the run's value checks."""

from __future__ import annotations

from glider_fmi.variables import Var


class _Range:
    """A closed-below interval ``[low, inf)`` (or every finite value)."""

    def __init__(self, low: float | None = None) -> None:
        self.low = low

    def contains(self, value: float) -> bool:
        return (
            value == value
            and abs(value) != float("inf")
            and (self.low is None or value >= self.low)
        )

    def describe(self, integer: bool = False) -> str:
        kind = "an integer" if integer else "a finite value"
        return f"{kind} in (-inf, inf)" if self.low is None else f"{kind} in [{self.low:g}, inf)"


VARIABLES = (
    Var("theta_in", "input", "rad", "pitch measured by the plant's sensor", 0.0),
    Var("theta_out", "output", "rad", "pitch with bias and noise, to the observer"),
    Var("bias", "parameter", "rad", "constant offset", 0.0, tunable=True, valid=_Range()),
    Var(
        "noise_std",
        "parameter",
        "rad",
        "standard deviation of the noise",
        0.0,
        tunable=True,
        valid=_Range(0.0),
    ),  # fmt: skip
    Var(
        "seed", "parameter", "1", "seed of the noise generator", 0, type="Integer", valid=_Range()
    ),  # fmt: skip
)
