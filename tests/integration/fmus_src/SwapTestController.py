"""A controller that is not ours, for the swap test: a plain P law on the glide angle
with its own (independently computed) equilibrium; output updated in doStep."""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

ALPHA_E = 0.39 / 14.7
KDE = 3.15 + 282.8 * ALPHA_E**2
KLE = 303.6 * ALPHA_E
THETA_GE = math.atan2(-KDE, KLE)


class SwapTestController(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.V_hat = 0.24
        self.theta_g_hat = THETA_GE
        self.delta_cmd = 0.0
        self.gain = 0.5
        self.register_variable(Real("V_hat", causality=Fmi2Causality.input))
        self.register_variable(Real("theta_g_hat", causality=Fmi2Causality.input))
        self.register_variable(Real("delta_cmd", causality=Fmi2Causality.output))
        self.register_variable(
            Real("gain", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        )

    def to_xml(self, model_options=None):
        root = super().to_xml(model_options or {})
        for unknown in root.find("ModelStructure").find("Outputs"):
            unknown.set("dependencies", "")  # computed in doStep: no feedthrough
        return root

    def do_step(self, current_time, step_size):
        self.delta_cmd = max(-1.0, min(1.0, -self.gain * (self.theta_g_hat - THETA_GE)))
        return True
