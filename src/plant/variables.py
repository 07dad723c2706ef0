"""The plant FMU's variables in value-reference order (:class:`glider_fmi.variables.Var`:
name, causality, unit, description, start, type, valid range): read by the slave, and
without pythonfmu by the run's value checks (issue 48)."""

from __future__ import annotations

import math

from glider_fmi.variables import Var
from glider_plant.fmi_vars import model_constant_vars
from glider_plant.params import NON_NEGATIVE, POSITIVE, Range

R90 = math.pi / 2

VARIABLES = (
    Var("delta_cmd", "input", "rad", "commanded tail angle (servo set-point)"),
    Var("F_x", "input", "N", "disturbance force, inertial x (forward-horizontal)"),
    Var("F_z", "input", "N", "disturbance force, inertial z (down)"),
    Var("M_y", "input", "N.m", "disturbance pitch moment (nose up positive)"),
    Var("theta_meas", "output", "rad", "measured pitch: true pitch + sensor noise"),
    Var("theta", "output", "rad", "true pitch theta_g + alpha"),
    Var("V", "output", "m/s", "speed"),
    Var("theta_g", "output", "rad", "glide angle (up positive)"),
    Var("alpha", "output", "rad", "angle of attack"),
    Var("omega2", "output", "rad/s", "pitch rate"),
    Var("delta", "output", "rad", "actual tail angle (servo output)"),
    Var("x", "output", "m", "horizontal position"),
    Var("z", "output", "m", "depth (positive down)"),
    *model_constant_vars(),
    Var("tau_servo", "parameter", "s", "tail servo time constant", 0.01, valid=Range(0.0)),
    Var("delta_max", "parameter", "rad", "tail angle limit", R90, valid=Range(0.0, math.pi)),
    Var(
        "noise_std",
        "parameter",
        "rad",
        "sensor noise standard deviation",
        0.0,
        valid=NON_NEGATIVE,
    ),
    Var(
        "noise_seed",
        "parameter",
        "1",
        "sensor noise seed",
        0,
        type="Integer",
        valid=Range(0, 2**31 - 1, False, False),
    ),
    Var("h_max", "parameter", "s", "largest internal RK4 sub-step", 0.02, valid=POSITIVE),
    Var("V_0", "parameter", "m/s", "initial speed", 0.2, valid=POSITIVE),
    Var(
        "theta_g_0",
        "parameter",
        "rad",
        "initial glide angle",
        math.radians(-35.0),
        valid=Range(-math.pi, math.pi),
    ),
    Var(
        "alpha_0",
        "parameter",
        "rad",
        "initial angle of attack",
        math.radians(1.0),
        valid=Range(-R90, R90),
    ),
    Var("omega2_0", "parameter", "rad/s", "initial pitch rate", 0.0, valid=Range()),
    Var("delta_0", "parameter", "rad", "initial tail angle", 0.0, valid=Range()),
    Var("x_0", "parameter", "m", "initial horizontal position", 0.0, valid=Range()),
    Var("z_0", "parameter", "m", "initial depth", 0.0, valid=Range()),
    # the continuous states' derivatives (last: new value references after the others)
    *(
        Var(f"der({x})", "local", unit, f"time derivative of {x}")
        for x, unit in (
            ("V", "m/s2"),
            ("theta_g", "rad/s"),
            ("alpha", "rad/s"),
            ("omega2", "rad/s2"),
            ("x", "m/s"),
            ("z", "m/s"),
            ("delta", "rad/s"),
        )
    ),  # fmt: skip
)
