"""The controller FMU's variables in value-reference order (:class:`glider_fmi.variables.Var`:
name, causality, unit, description, start, type, valid range): read by the slave, and
without pythonfmu by the run's value checks (issue 48)."""

from __future__ import annotations

import math

from glider_fmi.variables import Var
from glider_plant.fmi_vars import model_constant_vars
from glider_plant.model import equilibrium
from glider_plant.params import NON_NEGATIVE, POSITIVE, GliderParams, Range

_EQ = equilibrium(GliderParams())

VARIABLES = (
    Var("V_hat", "input", "m/s", "speed fed back (estimate)", _EQ.V),
    Var("theta_g_hat", "input", "rad", "glide angle fed back (estimate)", _EQ.theta_g),
    Var("delta_cmd", "output", "rad", "tail command"),
    Var(
        "law",
        "parameter",
        "1",
        "0 open loop, 1 passivity-based, 2 P, 3 PI",
        1,
        type="Integer",
        tunable=True,
        valid=Range(0, 3, False, False),
    ),
    Var(
        "K_c",
        "parameter",
        "1",
        "passivity-law gain (Eq. 28)",
        10.0,
        tunable=True,
        valid=POSITIVE,
    ),
    # defaults that settle the default scenario (P: 10.2 s, PI: 14.9 s); the paper's
    # K_P = 2, K_I = 1 stall it (scenarios paper-p-gains, paper-pi-gains)
    Var("K_P", "parameter", "1", "P/PI proportional gain", 0.5, tunable=True, valid=NON_NEGATIVE),
    Var("K_I", "parameter", "Hz", "PI integral gain", 0.2, tunable=True, valid=NON_NEGATIVE),
    Var(
        "delta_open",
        "parameter",
        "rad",
        "tail angle of the open-loop law",
        0.0,
        tunable=True,
        valid=Range(-math.pi, math.pi),
    ),
    Var(
        "t_enable",
        "parameter",
        "s",
        "before this time the output is delta_open",
        0.0,
        tunable=True,
        valid=Range(),
    ),
    Var(
        "delta_max",
        "parameter",
        "rad",
        "tail angle limit",
        math.pi / 2,
        valid=Range(0.0, math.pi),
    ),
    *model_constant_vars(),
)
