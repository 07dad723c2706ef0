"""GliderPlant: glider body (Eqs. (6)-(9)) + kinematics + tail servo + pitch sensor.

Thin pythonfmu wrapper: it declares the variables and calls :mod:`glider_plant.model`.
"""

from __future__ import annotations

from glider_fmi.slave_base import GliderSlave
from glider_plant.jacobian import PLANT_INPUTS, PLANT_STATES, plant_derivatives, plant_jacobian
from glider_plant.model import PitchSensor, StallError, plant_step, saturate
from glider_plant.params import GliderParams
from glider_plant.variables import VARIABLES as _VARIABLES


def _initial_dependencies(
    step: dict[str, tuple[str, ...]], constants: dict[str, tuple[str, ...]]
) -> dict[str, tuple[str, ...]]:
    """What each state derivative depends on in Initialization Mode: the start values of the
    states it depends on after it (``V`` -> ``V_0``), the inputs, its constants."""
    start = {x: f"{x}_0" for x in PLANT_STATES}
    return {d: tuple(start.get(k, k) for k in knowns) + constants[d] for d, knowns in step.items()}


class GliderPlant(GliderSlave):
    """Underwater glider in the sagittal plane with a whale-tail control surface."""

    description = "Underwater glider (sagittal plane), tail servo and pitch sensor"
    VARIABLES = _VARIABLES
    # the knowns each state derivative depends on (plant_jacobian's nonzero columns, tested)
    DERIVATIVE_DEPENDENCIES = {
        "der(V)": ("V", "theta_g", "alpha", "delta", "F_x", "F_z"),
        "der(theta_g)": ("V", "theta_g", "alpha", "delta", "F_x", "F_z"),
        "der(alpha)": ("V", "theta_g", "alpha", "omega2", "delta", "F_x", "F_z"),
        "der(omega2)": ("V", "alpha", "omega2", "delta", "M_y"),
        "der(x)": ("V", "theta_g"),
        "der(z)": ("V", "theta_g"),
        "der(delta)": ("delta", "delta_cmd"),
    }

    # ... and the model constants and servo parameters of each one's equation
    DERIVATIVE_CONSTANTS = {
        "der(V)": ("m", "K_D0", "K_D", "K_Fdelta", "K_udelta", "m0", "g"),
        "der(theta_g)": ("m", "K_L0", "K_L", "K_Fdelta", "K_udelta", "m0", "g"),
        "der(alpha)": ("m", "K_L0", "K_L", "K_Fdelta", "K_udelta", "m0", "g"),
        "der(omega2)": ("J2", "K_M0", "K_M", "K_q", "K_udelta"),
        "der(x)": (),
        "der(z)": (),
        "der(delta)": ("tau_servo", "delta_max"),
    }
    # in Initialization Mode: the initial state, nothing of the inputs (no feedthrough)
    INITIAL_DEPENDENCIES = {
        "theta_meas": ("theta_g_0", "alpha_0", "noise_std", "noise_seed"),
        "theta": ("theta_g_0", "alpha_0"),
        "V": ("V_0",),
        "theta_g": ("theta_g_0",),
        "alpha": ("alpha_0",),
        "omega2": ("omega2_0",),
        "delta": ("delta_0",),
        "x": ("x_0",),
        "z": ("z_0",),
        # the state derivatives: of the start values, the inputs and the constants
        **_initial_dependencies(DERIVATIVE_DEPENDENCIES, DERIVATIVE_CONSTANTS),
    }
    INTERNAL_STATE = ("_p", "_sensor", "_state")
    STATE_DERIVATIVES = {f"der({x})": x for x in PLANT_STATES}
    COMPUTED = tuple(STATE_DERIVATIVES)  # from the state and the inputs when read
    # plant_jacobian's rows: the derivatives, then the pitch (theta_meas: theta + noise)
    JACOBIAN_ROWS = {**{d: i for i, d in enumerate(STATE_DERIVATIVES)}, "theta": 7,
                     "theta_meas": 7}  # fmt: skip
    JACOBIAN_COLUMNS = PLANT_STATES + PLANT_INPUTS

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        for v in self.vars.values():
            if v.name in self.STATE_DERIVATIVES:
                k = PLANT_STATES.index(self.STATE_DERIVATIVES[v.name])
                v.getter = lambda k=k: self._derivatives()[k]
        self._index_reals()

    def _point(self) -> tuple:
        """The arguments of plant_derivatives and plant_jacobian now: the state (before
        initialisation the one the parameters give) and the inputs."""
        if self._initialized:
            x, delta, p = self._state, self.delta, self._p
        else:
            x = (self.V_0, self.theta_g_0, self.alpha_0, self.omega2_0, self.x_0, self.z_0)
            delta, p = self.delta_0, GliderParams.from_mapping(vars(self))
        return (x, delta, self.delta_cmd, (self.F_x, self.F_z, self.M_y), p, self.tau_servo,
                self.delta_max)  # fmt: skip

    def _derivatives(self) -> tuple[float, ...]:
        return plant_derivatives(*self._point())

    def jacobian(self) -> list[float]:
        return [v for row in plant_jacobian(*self._point()) for v in row]

    def initialize(self) -> None:
        self._p = GliderParams.from_mapping(vars(self))
        self._sensor = PitchSensor(self.noise_std, self.noise_seed)
        if abs(self.delta_0) > self.delta_max:
            self.fail(f"delta_0 = {self.delta_0!r} is invalid: expected |delta_0| <= delta_max")
        self._state = (self.V_0, self.theta_g_0, self.alpha_0, self.omega2_0, self.x_0, self.z_0)
        self.delta = self.delta_0
        self._publish()

    def _publish(self) -> None:
        self.V, self.theta_g, self.alpha, self.omega2, self.x, self.z = self._state
        self.theta = self.theta_g + self.alpha
        self.theta_meas = self._sensor.measure(self.theta)

    def step(self, t: float, h: float) -> bool:
        self.check_inputs()
        cmd = saturate(self.delta_cmd, self.delta_max)
        try:
            self._state, self.delta = plant_step(
                self._state,
                self.delta,
                cmd,
                h,
                self._p,
                self.tau_servo,
                (self.F_x, self.F_z, self.M_y),
                self.h_max,
            )
        except StallError as err:
            return self.discard(f"{err} at t = {t:g} s")
        self._publish()
        return True
