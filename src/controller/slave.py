"""GliderController: passivity-based law (Eqs. (23)-(30)), P, PI, open loop.

Thin pythonfmu wrapper over :mod:`glider_controller.laws`. The output has direct
feedthrough: ``delta_cmd`` is computed from the inputs set at the same communication
point, when it is read.
"""

from __future__ import annotations

from glider_controller.laws import Law, PIController, passivity_law
from glider_controller.variables import VARIABLES as _VARIABLES
from glider_fmi.slave_base import GliderSlave
from glider_plant.model import equilibrium, saturate
from glider_plant.params import GliderParams


class GliderController(GliderSlave):
    """Tail-angle controller for the steady glide."""

    description = "Passivity-based, P, PI or open-loop tail-angle controller"
    VARIABLES = _VARIABLES
    FEEDTHROUGH = {"delta_cmd": ("V_hat", "theta_g_hat")}
    # in Initialization Mode the laws run as after Exit (the PI integrator is 0: K_I
    # does not count); the passivity law uses the equilibrium (K_M0 .. g) and K_Fdelta,
    # K_udelta
    INITIAL_DEPENDENCIES = {
        "delta_cmd": ("V_hat", "theta_g_hat", "law", "K_c", "K_P", "delta_open", "t_enable",
                      "delta_max", "K_M0", "K_M", "K_L0", "K_L", "K_D0", "K_D", "m0", "g",
                      "K_Fdelta", "K_udelta"),
    }  # fmt: skip
    COMPUTED = ("delta_cmd",)  # read through its getter, not the attribute
    INTERNAL_STATE = ("_p", "_eq", "_pi")

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        # delta_cmd is computed when read (direct feedthrough)
        self.vars[self._vr("delta_cmd")].getter = self.command
        self._index_reals()

    def _vr(self, name: str) -> int:
        return next(vr for vr, v in self.vars.items() if v.name == name)

    def initialize(self) -> None:
        self._p = GliderParams.from_mapping(vars(self))
        self._eq = equilibrium(self._p)
        self._pi = PIController(self.K_P, self.K_I, self.delta_max)

    def _enabled(self) -> bool:
        return self._time >= self.t_enable - 1e-9

    def command(self) -> float:
        """Tail command (rad) for the current inputs and time."""
        law = self.law
        # in Initialization Mode the laws run as after Exit (initialize() ran before)
        initialized = self._initialized or self._in_init
        if law == 0 or not initialized or self._time < self.t_enable - 1e-9:
            return saturate(self.delta_open, self.delta_max)
        if law == 1:
            return passivity_law(
                self.V_hat, self.theta_g_hat, self.K_c, self._p, self._eq, self.delta_max
            )
        pi = self._pi
        pi.K_P = self.K_P
        pi.K_I = self.K_I if law == Law.PI else 0.0
        return pi.output(self.theta_g_hat - self._eq.theta_g)

    def step(self, t: float, h: float) -> bool:
        self.check_inputs()
        if self.law == Law.PI and self._enabled():
            self._pi.K_P, self._pi.K_I = self.K_P, self.K_I
            self._pi.update(self.theta_g_hat - self._eq.theta_g, h)
        return True
