"""The observer FMU's variables in value-reference order (:class:`glider_fmi.variables.Var`:
name, causality, unit, description, start, type, valid range): read by the slave, and
without pythonfmu by the run's value checks (issue 48)."""

from __future__ import annotations

from glider_fmi.variables import Var
from glider_observer.filter import DEFAULT_F_CUTOFF, DEFAULT_F_SAMPLE
from glider_observer.model import DEFAULT_Q, DEFAULT_R
from glider_plant.fmi_vars import model_constant_vars
from glider_plant.model import equilibrium
from glider_plant.params import NON_NEGATIVE, POSITIVE, GliderParams, Range

_EQ = equilibrium(GliderParams())

VARIABLES = (
    Var("theta_meas", "input", "rad", "measured pitch", _EQ.theta_g + _EQ.alpha),
    Var("delta_cmd", "input", "rad", "tail command applied to the plant"),
    Var("theta_filt", "output", "rad", "pitch after the pre-filter"),
    Var("V_hat", "output", "m/s", "estimated speed"),
    Var("theta_g_hat", "output", "rad", "estimated glide angle"),
    Var("alpha_hat", "output", "rad", "estimated angle of attack"),
    Var("omega2_hat", "output", "rad/s", "estimated pitch rate"),
    Var("theta_hat", "output", "rad", "estimated pitch theta_g_hat + alpha_hat"),
    *model_constant_vars(),
    Var(
        "R",
        "parameter",
        "rad2",
        "measurement-noise variance in the Riccati design",
        DEFAULT_R,
        valid=POSITIVE,
    ),
    Var("Q_V", "parameter", "1", "process-noise weight on V", DEFAULT_Q[0], valid=POSITIVE),
    Var(
        "Q_theta_g",
        "parameter",
        "1",
        "process-noise weight on theta_g",
        DEFAULT_Q[1],
        valid=POSITIVE,
    ),
    Var(
        "Q_alpha",
        "parameter",
        "1",
        "process-noise weight on alpha",
        DEFAULT_Q[2],
        valid=POSITIVE,
    ),
    Var(
        "Q_omega2",
        "parameter",
        "1",
        "process-noise weight on omega2",
        DEFAULT_Q[3],
        valid=POSITIVE,
    ),
    Var(
        "filter_enabled",
        "parameter",
        "1",
        "pre-filter on (true) or bypassed",
        True,
        type="Boolean",
    ),
    Var(
        "f_sample",
        "parameter",
        "Hz",
        "pre-filter sampling frequency (= 1/step; glider-cosim sets it from the step)",
        DEFAULT_F_SAMPLE,
        valid=POSITIVE,
    ),
    Var(
        "f_cutoff",
        "parameter",
        "Hz",
        "pre-filter cut-off frequency",
        DEFAULT_F_CUTOFF,
        valid=POSITIVE,
    ),
    Var(
        "start_at_equilibrium",
        "parameter",
        "1",
        "start the estimate at the model's equilibrium (ignore *_hat_0)",
        True,
        type="Boolean",
    ),
    Var("V_hat_0", "parameter", "m/s", "initial speed estimate", _EQ.V, valid=POSITIVE),
    Var(
        "theta_g_hat_0",
        "parameter",
        "rad",
        "initial glide-angle estimate",
        _EQ.theta_g,
        valid=Range(),
    ),
    Var(
        "alpha_hat_0",
        "parameter",
        "rad",
        "initial angle-of-attack estimate",
        _EQ.alpha,
        valid=Range(),
    ),
    Var("omega2_hat_0", "parameter", "rad/s", "initial pitch-rate estimate", 0.0, valid=Range()),
    Var("h_max", "parameter", "s", "largest internal RK4 sub-step", 0.02, valid=POSITIVE),
    Var(
        "t_start",
        "parameter",
        "s",
        "time the observer is initialised (before it: initial estimate held, no filtering)",
        0.0,
        valid=NON_NEGATIVE,
    ),
)
