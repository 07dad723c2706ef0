"""The noise block's pure model (no FMI): the measured pitch plus a constant bias and
zero-mean Gaussian noise, one sample per communication step from a seeded generator."""

from __future__ import annotations

import math
import random


class NoiseError(ValueError):
    """A parameter of the noise block out of its range (names it, its value and the range)."""


class PitchNoise:
    """Bias and Gaussian noise added to a pitch signal.

    Parameters
    ----------
    bias : float
        Constant offset added to the signal, rad.
    noise_std : float
        Standard deviation of the noise, rad (0: none).
    seed : int
        Seed of the generator: the same seed gives the same sequence.
    """

    def __init__(self, bias: float = 0.0, noise_std: float = 0.0, seed: int = 0) -> None:
        if not math.isfinite(bias):
            raise NoiseError(f"bias = {bias!r} is invalid: expected a finite value (rad)")
        if not (math.isfinite(noise_std) and noise_std >= 0.0):
            raise NoiseError(f"noise_std = {noise_std!r} is invalid: expected a finite value >= 0")
        self.bias = bias
        self.noise_std = noise_std
        self._rng = random.Random(int(seed))
        self.sample = 0.0

    def draw(self) -> None:
        """Draw the next noise sample (rad), held until the next draw."""
        self.sample = self._rng.gauss(0.0, self.noise_std) if self.noise_std > 0.0 else 0.0

    def apply(self, theta: float) -> float:
        """``theta`` with the bias and the current noise sample (rad)."""
        return theta + self.bias + self.sample
