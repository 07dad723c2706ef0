"""An independent glider plant for the swap test: Eqs. (6)-(9) written separately, in
another style (state as a list, explicit midpoint rule with 40 sub-steps per step, no
tail servo: the tail follows the command at once). Shares no code with glider_plant."""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

CONST = dict(
    m=10.0,
    J2=0.08,
    KL0=0.0,
    KL=303.6,
    KD0=3.15,
    KD=282.8,
    Kq=-0.8,
    KM0=0.39,
    KM=-14.7,
    KF=29.5,
    m0=0.05,
    g=9.81,
)


def rhs(s, u, c):
    V, th, al, w = s
    lift = (c["KL0"] + c["KL"] * al) * V * V
    drag = (c["KD0"] + c["KD"] * al * al) * V * V
    force = c["KF"] * V * V * u
    gam = (-c["m0"] * c["g"] * math.cos(th) + lift + force * math.cos(al)) / (c["m"] * V)
    return [
        (-c["m0"] * c["g"] * math.sin(th) - drag + force * math.sin(al)) / c["m"],
        gam,
        w - gam,
        (c["KM0"] + c["KM"] * al + c["Kq"] * w - c["KM"] * u) * V * V / c["J2"],
        V * math.cos(th),
        -V * math.sin(th),
    ]


class SwapTestPlant(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.delta_cmd = self.F_x = self.F_z = self.M_y = 0.0
        self.V_0, self.theta_g_0, self.alpha_0 = 0.2, math.radians(-35.0), math.radians(1.0)
        self.state = [self.V_0, self.theta_g_0, self.alpha_0, 0.0, 0.0, 0.0]
        for n in ("delta_cmd", "F_x", "F_z", "M_y"):
            self.register_variable(Real(n, causality=Fmi2Causality.input))
        for i, n in enumerate(("V", "theta_g", "alpha", "omega2", "x", "z")):
            self.register_variable(
                Real(n, causality=Fmi2Causality.output, getter=lambda i=i: self.state[i])
            )
        self.register_variable(
            Real(
                "theta",
                causality=Fmi2Causality.output,
                getter=lambda: self.state[1] + self.state[2],
            )
        )
        self.register_variable(
            Real(
                "theta_meas",
                causality=Fmi2Causality.output,
                getter=lambda: self.state[1] + self.state[2],
            )
        )
        self.register_variable(
            Real("delta", causality=Fmi2Causality.output, getter=lambda: self.delta_cmd)
        )
        for n in ("V_0", "theta_g_0", "alpha_0"):
            self.register_variable(
                Real(n, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
            )

    def to_xml(self, model_options=None):
        root = super().to_xml(model_options or {})
        for unknown in root.find("ModelStructure").find("Outputs"):
            unknown.set("dependencies", "")  # no direct feedthrough
        return root

    def exit_initialization_mode(self):
        self.state = [self.V_0, self.theta_g_0, self.alpha_0, 0.0, 0.0, 0.0]

    def do_step(self, current_time, step_size):
        n = 40
        dt = step_size / n
        for _ in range(n):
            k1 = rhs(self.state[:4], self.delta_cmd, CONST)
            mid = [a + 0.5 * dt * b for a, b in zip(self.state, k1)]
            k2 = rhs(mid[:4], self.delta_cmd, CONST)
            self.state = [a + dt * b for a, b in zip(self.state, k2)]
        return self.state[0] > 1e-3
