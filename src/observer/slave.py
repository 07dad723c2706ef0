"""GliderObserver: Butterworth pre-filter (Sec. 5.1) + nonlinear observer (Sec. 4).

Thin pythonfmu wrapper over :mod:`glider_observer.filter` and :mod:`glider_observer.model`.
"""

from __future__ import annotations

from pythonfmu.enums import Fmi2Status

from glider_fmi.slave_base import GliderSlave
from glider_observer.filter import ButterworthFilter
from glider_observer.model import observer_gain, observer_step
from glider_observer.variables import VARIABLES as _VARIABLES
from glider_plant.model import StallError, equilibrium
from glider_plant.params import GliderParams

# the model constants the equilibrium's alpha, theta_g and V are computed from
_EQ_ALPHA = ("K_M0", "K_M")
_EQ_THETA_G = (*_EQ_ALPHA, "K_L0", "K_L", "K_D0", "K_D")
_EQ_V = (*_EQ_THETA_G, "m0", "g")


class GliderObserver(GliderSlave):
    """Estimates speed, glide angle, angle of attack and pitch rate from pitch alone."""

    description = "Butterworth pre-filter + nonlinear observer of the glider state"
    VARIABLES = _VARIABLES
    # in Initialization Mode: the pre-filter passes the measured pitch on; the estimate
    # starts at the model's equilibrium (the constants it is computed from) or at *_hat_0
    INITIAL_DEPENDENCIES = {
        "theta_filt": ("theta_meas",),
        "V_hat": ("start_at_equilibrium", "V_hat_0", *_EQ_V),
        "theta_g_hat": ("start_at_equilibrium", "theta_g_hat_0", *_EQ_THETA_G),
        "alpha_hat": ("start_at_equilibrium", "alpha_hat_0", *_EQ_ALPHA),
        "omega2_hat": ("start_at_equilibrium", "omega2_hat_0"),
        "theta_hat": (
            "start_at_equilibrium",
            "theta_g_hat_0",
            "alpha_hat_0",
            *_EQ_THETA_G,
        ),
    }
    INTERNAL_STATE = ("_p", "_H", "_filter", "_xh", "_step_warned")
    _step_warned = False  # a step that does not match f_sample was reported

    def initialize(self) -> None:
        self._p = GliderParams.from_mapping(vars(self))
        Q = (self.Q_V, self.Q_theta_g, self.Q_alpha, self.Q_omega2)
        self._H = observer_gain(self._p, self.R, Q)
        self._filter = ButterworthFilter(self.f_sample, self.f_cutoff)
        if self.start_at_equilibrium:
            e = equilibrium(self._p)
            self._xh = (e.V, e.theta_g, e.alpha, 0.0)
        else:
            self._xh = (self.V_hat_0, self.theta_g_hat_0, self.alpha_hat_0, self.omega2_hat_0)
        self.theta_filt = self.theta_meas
        self._step_warned = False
        self._publish()

    def _publish(self) -> None:
        self.V_hat, self.theta_g_hat, self.alpha_hat, self.omega2_hat = self._xh
        self.theta_hat = self.theta_g_hat + self.alpha_hat

    def step(self, t: float, h: float) -> bool:
        self.check_inputs()
        if self.filter_enabled and not self._step_warned and abs(h * self.f_sample - 1.0) > 1e-9:
            # the pre-filter runs once per step: its coefficients assume 1/step = f_sample
            self._step_warned = True
            self.log(
                f"{self.instance_name}: communication step {h:g} s does not match f_sample = "
                f"{self.f_sample:g} Hz (1/step = {1.0 / h:g} Hz): the pre-filter runs once per "
                "step, its coefficients assume f_sample",
                Fmi2Status.warning,
            )
        if t < self.t_start - 1e-9:  # not initialised yet (Sec. 5.2: 2 s after release)
            self.theta_filt = self.theta_meas
            return True
        self.theta_filt = self._filter(self.theta_meas) if self.filter_enabled else self.theta_meas
        try:
            self._xh = observer_step(
                self._xh,
                self.theta_filt,
                self._p.K_udelta * self.delta_cmd,
                h,
                self._p,
                self._H,
                self.h_max,
            )
        except StallError as err:
            return self.discard(f"observer estimate {err} at t = {t:g} s")
        self._publish()
        return True
