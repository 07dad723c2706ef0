"""The same sampled-data loop as the three FMUs under the Gauss-Seidel master, calling
the pure model code directly (no FMI): the reference for accuracy and FMI overhead."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from fmpy import read_model_description

from glider_controller.laws import Law, PIController, passivity_law
from glider_observer.filter import ButterworthFilter
from glider_observer.model import observer_gain, observer_step
from glider_plant.model import PitchSensor, equilibrium, plant_step, saturate
from glider_plant.params import GliderParams

from ..scenarios.fields import ScenarioError
from ..scenarios.sampling import with_sampling
from ..scenarios.scenario import Scenario
from ..scenarios.system import FMU_NAMES


def fmu_parameter_defaults(fmu: Path) -> dict[str, Any]:
    """Start values of an FMU's parameters and inputs (its model description is the source)."""
    conv = {"Real": float, "Integer": int, "Boolean": lambda v: str(v).lower() in ("true", "1")}
    md = read_model_description(str(fmu))
    return {
        v.name: conv[v.type](v.start)
        for v in md.modelVariables
        if v.causality in ("parameter", "input") and v.type in conv
    }


#: the contract's columns, in the order the master records them
COLUMNS = [
    "time", "plant.theta_meas", "plant.theta", "plant.V", "plant.theta_g", "plant.alpha",
    "plant.omega2", "plant.delta", "plant.x", "plant.z", "observer.theta_filt",
    "observer.V_hat", "observer.theta_g_hat", "observer.alpha_hat", "observer.omega2_hat",
    "observer.theta_hat", "controller.delta_cmd",
]  # fmt: skip


def _fmus(fmu_dir: str | Path | None) -> Path:
    """The folder whose FMUs give the parameter defaults; None: the cache (built there)."""
    from ..fmus.folders import prepare_fmus

    return prepare_fmus(fmu_dir, None)


def simulate_monolithic(
    scenario: Scenario,
    step: float | None = None,
    stop_time: float | None = None,
    row: Callable[[list[float]], Any] | None = None,
    fmu_dir: str | Path | None = None,
) -> np.ndarray:
    """Run the scenario's closed loop without FMI (Gauss-Seidel semantics).

    At ``t_k``: the sensor samples the pitch, the controller acts on the observer's
    estimate at ``t_k``, then the observer (pre-filter + Eq. (34)) and the plant advance
    over the step with those values held. Events are not supported.

    Parameter defaults come from the FMUs' model descriptions in ``fmu_dir`` (default:
    the per-user cache).

    Returns
    -------
    ndarray
        One row per communication point with :data:`COLUMNS`.
    """
    if scenario.events or scenario.fmus or scenario.inputs:
        raise ScenarioError(
            f"{scenario.source}: the monolithic loop supports no events, FMU swaps or inputs"
        )
    h = step if step is not None else scenario.step
    stop = stop_time if stop_time is not None else scenario.stop_time
    fmu_dir = _fmus(fmu_dir)
    params = with_sampling(scenario.parameters, h, scenario.source)  # f_sample follows h
    pp, op, cp = (
        {**fmu_parameter_defaults(fmu_dir / f"{name}.fmu"), **params.get(inst, {})}
        for inst, name in FMU_NAMES.items()
    )
    p, po, pc = (GliderParams.from_mapping(d) for d in (pp, op, cp))
    eq_c = equilibrium(pc)
    sensor = PitchSensor(pp["noise_std"], int(pp["noise_seed"]))
    x = (pp["V_0"], pp["theta_g_0"], pp["alpha_0"], pp["omega2_0"], pp["x_0"], pp["z_0"])
    delta = pp["delta_0"]
    H = observer_gain(po, op["R"], (op["Q_V"], op["Q_theta_g"], op["Q_alpha"], op["Q_omega2"]))
    filt = ButterworthFilter(op["f_sample"], op["f_cutoff"])
    e = equilibrium(po)
    xh = (e.V, e.theta_g, e.alpha, 0.0)
    if not op["start_at_equilibrium"]:
        xh = (op["V_hat_0"], op["theta_g_hat_0"], op["alpha_hat_0"], op["omega2_hat_0"])
    pi = PIController(cp["K_P"], cp["K_I"] if cp["law"] == Law.PI else 0.0, cp["delta_max"])
    feedback_state = scenario.feedback == "state"
    n = round(stop / h)
    rows = []
    theta_f = op["theta_meas"]  # the observer's pre-filter output before its first step
    for k in range(n + 1):
        t = k * h
        theta_meas = sensor.measure(x[1] + x[2])
        fb_V, fb_th = (x[0], x[1]) if feedback_state else (xh[0], xh[1])
        enabled = t >= cp["t_enable"] - 1e-9
        if not enabled or cp["law"] == Law.OPEN_LOOP:
            cmd = saturate(cp["delta_open"], cp["delta_max"])
        elif cp["law"] == Law.PASSIVITY:
            cmd = passivity_law(fb_V, fb_th, cp["K_c"], pc, eq_c, cp["delta_max"])
        else:
            cmd = pi.output(fb_th - eq_c.theta_g)
        r = [t, theta_meas, x[1] + x[2], x[0], x[1], x[2], x[3], delta, x[4], x[5], theta_f,
             *xh, xh[1] + xh[2], cmd]  # fmt: skip
        if row is not None:
            row(r)
        rows.append(r)
        if k == n:
            break
        dist = [0.0, 0.0, 0.0]
        for d in scenario.disturbances:
            dist[("plant.F_x", "plant.F_z", "plant.M_y").index(d.target)] += d.at(t)
        if t < op["t_start"] - 1e-9:  # the observer is not initialised yet
            theta_f = theta_meas
        else:
            theta_f = filt(theta_meas) if op["filter_enabled"] else theta_meas
            xh = observer_step(xh, theta_f, po.K_udelta * cmd, h, po, H, op["h_max"])
        if cp["law"] == Law.PI and enabled:
            pi.update(fb_th - eq_c.theta_g, h)
        x, delta = plant_step(
            x,
            delta,
            saturate(cmd, pp["delta_max"]),
            h,
            p,
            pp["tau_servo"],
            tuple(dist),
            pp["h_max"],
        )
    return np.array(rows)


def simulate_continuous(
    scenario: Scenario, output_step: float = 0.02, fmu_dir: str | Path | None = None
) -> np.ndarray:
    """The scenario's loop in continuous time: plant, servo, observer and controller
    integrated together with ``solve_ivp`` (no sampling, no pre-filter, no noise).

    Returns rows of (time, plant.theta_g, observer.theta_g_hat, controller.delta_cmd) on
    the ``output_step`` grid. Only the passivity law without events or disturbances.
    """
    from scipy.integrate import solve_ivp

    from glider_plant.model import derivatives

    if scenario.events or scenario.disturbances or scenario.fmus:
        raise ScenarioError(f"{scenario.source}: the continuous loop supports no events")
    fmu_dir = _fmus(fmu_dir)
    pp, op, cp = (
        {**fmu_parameter_defaults(fmu_dir / f"{name}.fmu"), **scenario.parameters.get(inst, {})}
        for inst, name in FMU_NAMES.items()
    )
    if cp["law"] != Law.PASSIVITY:
        raise ScenarioError(f"{scenario.source}: the continuous loop needs the passivity law")
    p, po, pc = (GliderParams.from_mapping(d) for d in (pp, op, cp))
    eq_c, e_o = equilibrium(pc), equilibrium(po)
    H = observer_gain(po, op["R"], (op["Q_V"], op["Q_theta_g"], op["Q_alpha"], op["Q_omega2"]))
    state_fb = scenario.feedback == "state"

    def command(y):
        fb = (y[0], y[1]) if state_fb else (y[5], y[6])
        return passivity_law(fb[0], fb[1], cp["K_c"], pc, eq_c, cp["delta_max"])

    def rhs(t, y):
        cmd = saturate(command(y), pp["delta_max"])
        dx = derivatives(t, tuple(y[:4]), p.K_udelta * y[4], p)
        dd = (cmd - y[4]) / pp["tau_servo"]
        xh = tuple(y[5:9])
        fo = derivatives(t, xh, po.K_udelta * command(y), po)
        err = (y[1] + y[2]) - (xh[1] + xh[2])
        return [*dx, dd, *(f + hk * err for f, hk in zip(fo, H, strict=True))]

    y0 = [pp["V_0"], pp["theta_g_0"], pp["alpha_0"], pp["omega2_0"], pp["delta_0"],
          e_o.V, e_o.theta_g, e_o.alpha, 0.0]  # fmt: skip
    n = round(scenario.stop_time / output_step)
    t = np.arange(n + 1) * output_step
    sol = solve_ivp(rhs, (0.0, t[-1]), y0, method="LSODA", t_eval=t, rtol=1e-10, atol=1e-12)
    cmd = [command(sol.y[:, k]) for k in range(sol.y.shape[1])]
    return np.column_stack([sol.t, sol.y[1], sol.y[6], cmd])
