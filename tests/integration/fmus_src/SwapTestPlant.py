"""A glider plant that is not ours, for the swap test.

Written from the paper's Eqs. (1)-(9) alone, sharing no code with glider_plant and in
another style: the state is a dict, the constants a module table, the integrator an
adaptive Dormand-Prince 5(4) pair (error-controlled sub-steps inside every communication
step), and there is no tail servo (the tail angle follows the command at once) and no
sensor noise. The disturbance force (F_x forward, F_z down, inertial) is projected on
the velocity and its upward normal with explicit unit vectors.

Variables follow the FMI contract of GliderPlant: inputs delta_cmd, F_x, F_z, M_y;
outputs theta_meas, theta, V, theta_g, alpha, omega2, delta, x, z.
"""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

# paper Sec. 3.3 (K_Fdelta read as 29.5 kg/m, u_delta = delta)
PAPER = {
    "m1": 10.0,
    "J2": 0.08,
    "KL0": 0.0,
    "KL": 303.6,
    "KD0": 3.15,
    "KD": 282.8,
    "Kq2": -0.8,
    "KM0": 0.39,
    "KM": -14.7,
    "KFd": 29.5,
    "m0": 0.05,
    "g": 9.81,
}
ORDER = ("V", "theta_g", "alpha", "omega2", "x", "z")

# Dormand-Prince 5(4) tableau
A = (
    (),
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
    (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84),
)
B5 = (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0)
B4 = (5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40)


def glider_rates(s, u, fx, fz, my):
    """d/dt of the state dict s (Eqs. (6)-(9) and the kinematics)."""
    c = PAPER
    V, tg, a, w = s["V"], s["theta_g"], s["alpha"], s["omega2"]
    q = V * V
    L = (c["KL0"] + c["KL"] * a) * q  # (1)
    D = (c["KD0"] + c["KD"] * a * a) * q  # (2)
    Fd = c["KFd"] * q * u  # (3)
    M2 = (c["KM0"] + c["KM"] * a + c["Kq2"] * w) * q  # (4)
    Md = -c["KM"] * u * q  # (5)
    # unit vectors in the inertial (x forward, z down) frame
    along = (math.cos(tg), -math.sin(tg))
    normal_up = (-math.sin(tg), -math.cos(tg))
    f_along = fx * along[0] + fz * along[1]
    f_normal = fx * normal_up[0] + fz * normal_up[1]
    weight = c["m0"] * c["g"]
    Vdot = -(weight * math.sin(tg) + D - Fd * math.sin(a) - f_along) / c["m1"]  # (6)
    tgdot = (-weight * math.cos(tg) + L + Fd * math.cos(a) + f_normal) / (c["m1"] * V)  # (7)
    return {
        "V": Vdot,
        "theta_g": tgdot,
        "alpha": w - tgdot,  # (8)
        "omega2": (M2 + Md + my) / c["J2"],  # (9)
        "x": V * math.cos(tg),
        "z": -V * math.sin(tg),
    }


def dopri_step(s, h, u, d):
    """One Dormand-Prince step: (5th-order state, error estimate)."""
    ks = []
    for i in range(7):
        si = {n: s[n] + h * sum(a * k[n] for a, k in zip(A[i], ks)) for n in ORDER}
        ks.append(glider_rates(si, u, *d))
    new = {n: s[n] + h * sum(b * k[n] for b, k in zip(B5, ks)) for n in ORDER}
    err = max(
        abs(h * sum((b5 - b4) * k[n] for b5, b4, k in zip(B5, B4, ks)))
        / (1e-10 + 1e-9 * max(abs(s[n]), abs(new[n])))
        for n in ORDER
    )
    return new, err


class SwapTestPlant(Fmi2Slave):
    author = "swap test"
    description = "Independent glider plant (paper Eqs. (1)-(9)), no servo, Dormand-Prince"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.delta_cmd = 0.0
        self.F_x = 0.0
        self.F_z = 0.0
        self.M_y = 0.0
        self.V_0 = 0.2
        self.theta_g_0 = math.radians(-35.0)
        self.alpha_0 = math.radians(1.0)
        self.omega2_0 = 0.0
        self.s = self._initial()
        self.h_try = 0.005
        for name in ("delta_cmd", "F_x", "F_z", "M_y"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ORDER:
            self.register_variable(
                Real(name, causality=Fmi2Causality.output, getter=lambda n=name: self.s[n])
            )
        for name in ("theta", "theta_meas"):
            self.register_variable(
                Real(
                    name,
                    causality=Fmi2Causality.output,
                    getter=lambda: self.s["theta_g"] + self.s["alpha"],
                )
            )
        self.register_variable(
            Real("delta", causality=Fmi2Causality.output, getter=lambda: self.delta_cmd)
        )
        for name in ("V_0", "theta_g_0", "alpha_0", "omega2_0"):
            self.register_variable(
                Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
            )

    def _initial(self):
        return {
            "V": self.V_0,
            "theta_g": self.theta_g_0,
            "alpha": self.alpha_0,
            "omega2": self.omega2_0,
            "x": 0.0,
            "z": 0.0,
        }

    def to_xml(self, model_options=None):
        root = super().to_xml(model_options or {})
        for unknown in root.find("ModelStructure").find("Outputs"):
            unknown.set("dependencies", "")  # outputs are states: no direct feedthrough
        return root

    def exit_initialization_mode(self):
        self.s = self._initial()

    def do_step(self, current_time, step_size):
        t, end = 0.0, step_size
        d = (self.F_x, self.F_z, self.M_y)
        while t < end - 1e-15:
            h = min(self.h_try, end - t)
            new, err = dopri_step(self.s, h, self.delta_cmd, d)
            if err <= 1.0:
                self.s, t = new, t + h
            grow = 0.9 * (1.0 / max(err, 1e-10)) ** 0.2
            self.h_try = h * min(5.0, max(0.2, grow))
            if self.s["V"] <= 1e-3:
                return False  # stalled: fmi2Discard
        return True
