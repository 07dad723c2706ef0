"""GliderPitchNoise: bias and Gaussian noise on the measured pitch, between the plant and
the observer.

Thin pythonfmu wrapper over :mod:`glider_noise.model`: it declares the variables and
calls the model. The output has direct feedthrough: ``theta_out`` is the input set at
the same communication point plus the bias and the step's noise sample.
"""

from __future__ import annotations

from glider_noise.model import PitchNoise
from glider_noise.variables import VARIABLES as _VARIABLES

from glider_fmi.slave_base import GliderSlave


class GliderPitchNoise(GliderSlave):
    """Sensor noise on the glider's pitch measurement."""

    description = "Bias and Gaussian noise on the measured pitch"
    VARIABLES = _VARIABLES
    FEEDTHROUGH = {"theta_out": ("theta_in",)}
    INITIAL_DEPENDENCIES = {"theta_out": ("theta_in", "bias")}
    COMPUTED = ("theta_out",)  # read through its getter
    INTERNAL_STATE = ("_noise",)

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        vr = next(vr for vr, v in self.vars.items() if v.name == "theta_out")
        self.vars[vr].getter = self.output
        self._index_reals()
        self._noise = PitchNoise()

    def initialize(self) -> None:
        self._noise = PitchNoise(self.bias, self.noise_std, self.seed)

    def output(self) -> float:
        """The pitch to the observer (rad)."""
        self._noise.bias = self.bias
        return self._noise.apply(self.theta_in)

    def step(self, t: float, h: float) -> bool:
        self.check_inputs()
        self._noise.draw()
        return True
