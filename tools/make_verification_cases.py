"""Write the input tables, parameters and options of the verification kit's cases.

Run once by a maintainer (``python tools/make_verification_cases.py``); what it writes
under ``cosim/verification/<component>/`` *is* the case (``<Case>_in.csv``,
``<Case>_par.csv``, ``<Case>_ref.opt``): the kit reads those files as data and never runs
this script. The references (``<Case>_ref.csv``) are then made by
``python -m glider_cosim.verify --write``.
"""

from __future__ import annotations

import math
import random
from pathlib import Path

from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

ROOT = Path(__file__).resolve().parents[1] / "cosim" / "verification"
STEP = 0.02
E = equilibrium(GliderParams())
PITCH = E.theta_g + E.alpha
D = math.radians
AT_EQ = {"V_0": E.V, "theta_g_0": E.theta_g, "alpha_0": E.alpha}


def pulse(t0: float, t1: float, value: float):
    return lambda t: value if t0 <= t + 1e-9 < t1 else 0.0


def step(t0: float, value: float, before: float = 0.0):
    return lambda t: value if t + 1e-9 >= t0 else before


def zero(t: float) -> float:
    return 0.0


_noise = random.Random(11)
NOISE = [_noise.gauss(0.0, 0.01) for _ in range(501)]

# component -> case -> (stop time, rtol, atol, parameters, inputs)
TIGHT = (1e-6, 1e-6)
CASES = {
    "plant": {
        "release": (10.0, *TIGHT, {}, {"delta_cmd": zero, "F_x": zero, "F_z": zero, "M_y": zero}),
        "tail_step": (10.0, *TIGHT, AT_EQ,
                      {"delta_cmd": step(2.0, D(1.0)), "F_x": zero, "F_z": zero, "M_y": zero}),
        "servo_jump": (2.0, *TIGHT, AT_EQ,
                       {"delta_cmd": step(0.5, D(10.0)), "F_x": zero, "F_z": zero, "M_y": zero}),
        "noise_seed": (10.0, *TIGHT, {**AT_EQ, "noise_std": 0.01, "noise_seed": 7},
                       {"delta_cmd": zero, "F_x": zero, "F_z": zero, "M_y": zero}),
        "pulse_fx": (8.0, *TIGHT, AT_EQ,
                     {"delta_cmd": zero, "F_x": pulse(2.0, 3.0, 0.2), "F_z": zero, "M_y": zero}),
        "pulse_fz": (8.0, *TIGHT, AT_EQ,
                     {"delta_cmd": zero, "F_x": zero, "F_z": pulse(2.0, 3.0, 0.2), "M_y": zero}),
        "pulse_my": (8.0, *TIGHT, AT_EQ,
                     {"delta_cmd": zero, "F_x": zero, "F_z": zero, "M_y": pulse(2.0, 3.0, 0.01)}),
        "stall": (15.0, 1e-6, 1e-4,
                  {"V_0": 0.2371, "theta_g_0": D(-22.58), "alpha_0": D(1.52), "delta_0": D(60.0)},
                  {"delta_cmd": lambda t: D(60.0), "F_x": zero, "F_z": zero, "M_y": zero}),
    },
    "observer": {
        "filter_step": (5.0, *TIGHT, {},
                        {"theta_meas": step(1.0, PITCH + D(2.0), PITCH), "delta_cmd": zero}),
        "wrong_start": (15.0, *TIGHT,
                        {"start_at_equilibrium": False, "V_hat_0": 1.2 * E.V,
                         "theta_g_hat_0": E.theta_g + D(5.0), "alpha_hat_0": E.alpha,
                         "omega2_hat_0": 0.0},
                        {"theta_meas": lambda t: PITCH, "delta_cmd": zero}),
        "noisy_pitch": (10.0, *TIGHT, {},
                        {"theta_meas": lambda t: PITCH + NOISE[round(t / STEP)],
                         "delta_cmd": zero}),
        "late_start": (10.0, *TIGHT, {"t_start": 2.0},
                       {"theta_meas": lambda t: PITCH + D(3.0) * math.exp(-t / 2) * math.cos(2 * t),
                        "delta_cmd": step(5.0, D(2.0))}),
    },
    "controller": {
        "open_loop": (5.0, *TIGHT, {"law": 0, "delta_open": D(5.0)},
                      {"V_hat": lambda t: E.V + 0.01 * math.cos(t),
                       "theta_g_hat": lambda t: E.theta_g + D(3.0) * math.sin(t)}),
        "passivity": (10.0, *TIGHT, {},
                      {"V_hat": lambda t: E.V + 0.01 * math.cos(t),
                       "theta_g_hat": lambda t: E.theta_g + D(3.0) * math.sin(t)}),
        "p": (10.0, *TIGHT, {"law": 2, "K_P": 2.0},
              {"V_hat": lambda t: E.V + 0.01 * math.cos(t),
               "theta_g_hat": lambda t: E.theta_g + D(3.0) * math.sin(t)}),
        "pi": (10.0, *TIGHT, {"law": 3, "K_P": 2.0, "K_I": 1.0},
               {"V_hat": lambda t: E.V,
                "theta_g_hat": lambda t: E.theta_g + D(2.0) + D(2.0) * math.sin(t)}),
        "saturation": (10.0, *TIGHT, {"law": 2, "K_P": 2.0, "delta_max": D(10.0)},
                       {"V_hat": lambda t: E.V,
                        "theta_g_hat": lambda t: E.theta_g + D(20.0) * math.sin(0.6 * t)}),
        "anti_windup": (10.0, *TIGHT, {"law": 3, "K_P": 1.0, "K_I": 2.0, "delta_max": D(5.0)},
                        {"V_hat": lambda t: E.V,
                         "theta_g_hat": step(4.0, E.theta_g - D(2.0), E.theta_g + D(20.0))}),
        "enable_time": (6.0, *TIGHT, {"t_enable": 3.0, "delta_open": D(2.0)},
                        {"V_hat": lambda t: E.V + 0.01 * math.cos(t),
                         "theta_g_hat": lambda t: E.theta_g + D(3.0) * math.sin(t)}),
    },
}  # fmt: skip


def text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value)


def main() -> None:
    for component, cases in CASES.items():
        folder = ROOT / component
        folder.mkdir(parents=True, exist_ok=True)
        for name, (stop, rtol, atol, params, inputs) in cases.items():
            n = round(stop / STEP)
            lines = [",".join(["time", *inputs])]
            for k in range(n + 1):
                t = round(k * STEP, 10)
                lines.append(",".join([repr(t), *(repr(float(f(t))) for f in inputs.values())]))
            (folder / f"{name}_in.csv").write_text("\n".join(lines) + "\n")
            par = folder / f"{name}_par.csv"
            if params:
                rows = ["name,value", *(f"{k},{text(v)}" for k, v in params.items())]
                par.write_text("\n".join(rows) + "\n")
            else:
                par.unlink(missing_ok=True)
            opt = (f"StartTime, 0.0\nStopTime, {stop!r}\nStepSize, {STEP!r}\n"
                   f"RelTol, {rtol!r}\nAbsTol, {atol!r}\n")  # fmt: skip
            (folder / f"{name}_ref.opt").write_text(opt)
            print(f"{component}/{name}: {n + 1} input rows")


if __name__ == "__main__":
    main()
