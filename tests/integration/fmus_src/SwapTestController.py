"""A controller that is not ours, for the swap test: a plain proportional law on the glide
angle, written with pythonfmu alone (no shared code, pythonfmu's own model description).

    delta_cmd = clip(-K_P * (theta_g_hat - theta_ref), -delta_lim, delta_lim)

theta_ref is the steady glide angle of the paper's Sec. 3.3 constants, computed here
from Sec. 2.1: alpha_e = -K_M0 / K_M, theta_ge = atan(-K_De / K_Le). The command is
computed in do_step and held over the next step (a sampled controller).
"""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

_ALPHA_E = 0.39 / 14.7
THETA_REF = math.atan(-(3.15 + 282.8 * _ALPHA_E**2) / (303.6 * _ALPHA_E))


class SwapTestController(Fmi2Slave):
    author = "swap test"
    description = "Foreign P controller on the glide angle"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.V_hat = 0.24
        self.theta_g_hat = THETA_REF
        self.delta_cmd = 0.0
        self.K_P = 0.5
        self.theta_ref = THETA_REF
        self.delta_lim = math.radians(30.0)
        self.register_variable(Real("V_hat", causality=Fmi2Causality.input))
        self.register_variable(Real("theta_g_hat", causality=Fmi2Causality.input))
        self.register_variable(Real("delta_cmd", causality=Fmi2Causality.output))
        for name in ("K_P", "theta_ref", "delta_lim"):
            self.register_variable(
                Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
            )

    def do_step(self, current_time, step_size):
        u = -self.K_P * (self.theta_g_hat - self.theta_ref)
        self.delta_cmd = max(-self.delta_lim, min(self.delta_lim, u))
        return True
