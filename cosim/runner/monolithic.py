"""The same sampled-data loop as the three FMUs under the Gauss-Seidel master, calling
the model code directly (no FMI): the reference for accuracy and FMI overhead.

:func:`simulate_monolithic` calls the Python models. :class:`NativeMonolithic` is the
native flavor's floor: ``monolithic.c`` (next to this module) and the native FMUs' C
models (``src/<part>/<part>_model.c``), built as the FMUs are (flags, link-time
optimisation) into a helper of the FMU cache (``fmus.helpers.build_helper``),
runs the same loop in C. Its rows are bit for bit those of the native co-simulation
(tested), so its time is what the models cost, and the native flavor's time per macro
step minus it is what FMI and the master add (``native_monolithic_us_per_macro_step``).
"""

from __future__ import annotations

import ctypes
import time
from collections.abc import Callable
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np

from glider_controller.laws import Law, PIController, passivity_law
from glider_observer.filter import ButterworthFilter
from glider_observer.model import observer_gain, observer_step
from glider_plant.model import PitchSensor, equilibrium, plant_step, saturate
from glider_plant.params import GliderParams

from ..components import component, fmi_folder
from ..fmus.helpers import build_helper
from ..fmus.variables import parameter_defaults
from ..scenarios.fields import ScenarioError
from ..scenarios.sampling import with_sampling
from ..scenarios.scenario import Scenario

#: the loop this module writes out without FMI: the paper's three components (registry
#: names; their models are imported above, their C models compiled below)
LOOP = ("plant", "observer", "controller")

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


def loop_parameters(
    scenario: Scenario, step: float, fmu_dir: str | Path | None = None, what: str = "monolithic"
) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    """The plant's, observer's and controller's parameters and start values for a loop
    without FMI: the FMUs' defaults (their model descriptions in ``fmu_dir``, default the
    per-user cache), the scenario's values over them, ``f_sample`` following ``step`` (s).

    Raises
    ------
    ScenarioError
        The scenario has events, FMU swaps, inputs or added components (the loops have
        none of them).
    """
    if scenario.events or scenario.fmus or scenario.inputs:
        raise ScenarioError(
            f"{scenario.source}: the {what} loop supports no events, FMU swaps or inputs"
        )
    if scenario.components:
        raise ScenarioError(
            f"{scenario.source}: the {what} loop runs the plant, observer and controller "
            f"only, not {', '.join(scenario.components)}; run it with --loop fmpy"
        )
    fmu_dir = _fmus(fmu_dir)
    params = with_sampling(scenario.parameters, step, scenario.source)  # f_sample follows h
    pp, op, cp = (
        {**parameter_defaults(fmu_dir / f"{component(inst).model}.fmu"), **params.get(inst, {})}
        for inst in LOOP
    )
    return pp, op, cp


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
    h = step if step is not None else scenario.step
    stop = stop_time if stop_time is not None else scenario.stop_time
    pp, op, cp = loop_parameters(scenario, h, fmu_dir)
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
    n, rows = round(stop / h), []
    for k in range(n + 1):
        t = k * h
        theta_meas = sensor.measure(x[1] + x[2])
        if k == 0:  # the observer's pre-filter output before its first step: its input,
            theta_f = theta_meas  # set in Initialization Mode, passed on
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

    if scenario.events or scenario.disturbances or scenario.fmus or scenario.components:
        raise ScenarioError(f"{scenario.source}: the continuous loop supports no events")
    fmu_dir = _fmus(fmu_dir)
    pp, op, cp = (
        {
            **parameter_defaults(fmu_dir / f"{component(inst).model}.fmu"),
            **scenario.parameters.get(inst, {}),
        }
        for inst in LOOP
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


# ------------------------------------------------------------ the native floor, in C
SOURCE = Path(__file__).with_name("monolithic.c")
#: the C files compiled into the helper (each component's ``<name>_model.c`` of its
#: registered C sources), the headers they include
SOURCES = (
    SOURCE,
    *(f for n in LOOP for f in component(n).c_sources if f.name == f"{n}_model.c"),
)
HEADERS = (
    *(f for n in LOOP for f in component(n).c_sources if f.name == f"{n}_model.h"),
    fmi_folder() / "glider_fp.h",
)
#: the native FMUs' language and optimisation flags (glider_fmi.compile.CFLAGS)
FLAGS = ("-std=gnu11", "-O2", *(f"-I{p.parent}" for p in HEADERS))
_PARAMS = [f.name for f in fields(GliderParams)]


class _Params(ctypes.Structure):
    _fields_ = [(name, ctypes.c_double) for name in _PARAMS]


class _Setup(ctypes.Structure):
    """``MonoSetup`` of ``monolithic.c``: every field a double, in its order."""

    _fields_ = [
        ("plant", _Params), ("observer", _Params), ("controller", _Params),
        *((n, ctypes.c_double) for n in (
            "V_0", "theta_g_0", "alpha_0", "omega2_0", "x_0", "z_0", "delta_0",
            "plant_delta_max", "tau_servo", "plant_h_max", "noise_std", "noise_seed", "R")),
        ("Q", ctypes.c_double * 4),
        *((n, ctypes.c_double) for n in (
            "f_sample", "f_cutoff", "t_start", "observer_h_max", "theta_meas_start",
            "filter_enabled", "start_at_equilibrium", "V_hat_0", "theta_g_hat_0", "alpha_hat_0",
            "omega2_hat_0", "law", "K_c", "K_P", "K_I", "controller_delta_max", "delta_open",
            "t_enable", "feedback_state")),
    ]  # fmt: skip


_LIB: list[ctypes.CDLL] = []


def _library() -> ctypes.CDLL:
    if not _LIB:
        out = build_helper(
            "monolithic", SOURCES, HEADERS, FLAGS, "the native monolithic loop", lto=True
        )  # the models built as the FMUs build them
        lib = ctypes.CDLL(str(out))
        lib.glider_mono_state_size.restype = ctypes.c_size_t
        lib.glider_mono_init.restype = ctypes.c_int
        lib.glider_mono_run.restype = ctypes.c_long
        _LIB.append(lib)
    return _LIB[0]


def _setup(pp: dict[str, Any], op: dict[str, Any], cp: dict[str, Any], state_fb: bool) -> _Setup:
    s = _Setup()
    for part, values in (("plant", pp), ("observer", op), ("controller", cp)):
        params = GliderParams.from_mapping(values)
        for name in _PARAMS:
            setattr(getattr(s, part), name, float(getattr(params, name)))
    for name in ("V_0", "theta_g_0", "alpha_0", "omega2_0", "x_0", "z_0", "delta_0",
                 "tau_servo", "noise_std", "noise_seed"):  # fmt: skip
        setattr(s, name, float(pp[name]))
    s.plant_delta_max, s.plant_h_max = float(pp["delta_max"]), float(pp["h_max"])
    s.R = float(op["R"])
    s.Q[:] = [float(op[q]) for q in ("Q_V", "Q_theta_g", "Q_alpha", "Q_omega2")]
    for name in ("f_sample", "f_cutoff", "t_start", "filter_enabled", "start_at_equilibrium",
                 "V_hat_0", "theta_g_hat_0", "alpha_hat_0", "omega2_hat_0"):  # fmt: skip
        setattr(s, name, float(op[name]))
    s.observer_h_max, s.theta_meas_start = float(op["h_max"]), float(op["theta_meas"])
    s.law = float(Law(int(cp["law"])))
    for name in ("K_c", "K_P", "K_I", "delta_open", "t_enable"):
        setattr(s, name, float(cp[name]))
    s.controller_delta_max = float(cp["delta_max"])
    s.feedback_state = 1.0 if state_fb else 0.0
    return s


class NativeMonolithic:
    """The loop of one scenario in C, started and run in blocks.

    Parameters
    ----------
    scenario : Scenario
        No events, FMU swaps, inputs or disturbances; with the observer.
    step : float, optional
        The communication step (s); default the scenario's.
    fmu_dir : str or Path, optional
        The folder whose FMUs give the parameter defaults (default: the per-user cache).

    Raises
    ------
    ScenarioError
        The scenario has what the loop does not support, or a model refuses its
        parameters (the message of the FMU's own initialisation).
    OSError
        No C compiler for this machine.
    """

    def __init__(
        self, scenario: Scenario, step: float | None = None, fmu_dir: str | Path | None = None
    ) -> None:
        if scenario.disturbances:
            raise ScenarioError(
                f"{scenario.source}: the native monolithic loop has no disturbances"
            )
        if not scenario.observer:
            raise ScenarioError(
                f"{scenario.source}: the native monolithic loop runs the observer: "
                "with_observer = false is not supported"
            )
        self.step = step if step is not None else scenario.step
        pp, op, cp = loop_parameters(scenario, self.step, fmu_dir, "native monolithic")
        self._lib = _library()
        self._setup = _setup(pp, op, cp, scenario.feedback == "state")
        self._state = ctypes.create_string_buffer(self._lib.glider_mono_state_size())
        self._msg = ctypes.create_string_buffer(1024)
        self.source = scenario.source
        self.reset()

    def reset(self) -> None:
        """Back to the start (the models initialised again from the parameters)."""
        if self._lib.glider_mono_init(self._state, ctypes.byref(self._setup), self._msg,
                                      len(self._msg)):  # fmt: skip
            raise ScenarioError(f"{self.source}: {self._msg.value.decode()}")

    def run(self, n_steps: int) -> tuple[np.ndarray, str | None]:
        """The rows at times ``0, h, ..., n_steps h`` (:data:`COLUMNS`) and None, or the
        rows up to the step where a model stopped the run and its message."""
        rows = np.empty((n_steps + 1, len(COLUMNS)))
        done = self._lib.glider_mono_run(
            self._state, ctypes.c_double(self.step), ctypes.c_long(0), ctypes.c_long(n_steps + 1),
            1, ctypes.c_void_p(rows.ctypes.data), self._msg, len(self._msg),
        )  # fmt: skip
        if done == n_steps + 1:
            return rows, None
        return rows[:done], self._msg.value.decode()


def simulate_native_monolithic(
    scenario: Scenario,
    step: float | None = None,
    stop_time: float | None = None,
    fmu_dir: str | Path | None = None,
) -> np.ndarray:
    """Run the scenario's closed loop with the native FMUs' C models, without FMI.

    Parameters
    ----------
    scenario : Scenario
        No events, FMU swaps, inputs or disturbances.
    step, stop_time : float, optional
        Communication step and end time (s); default the scenario's.
    fmu_dir : str or Path, optional
        The folder whose FMUs give the parameter defaults (default: the per-user cache).

    Returns
    -------
    ndarray
        One row per communication point with :data:`COLUMNS` (fewer when a model stops
        the run).
    """
    loop = NativeMonolithic(scenario, step, fmu_dir)
    stop = stop_time if stop_time is not None else scenario.stop_time
    return loop.run(round(stop / loop.step))[0]


def seconds_per_step(scenario: Scenario, fmu_dir: str | Path | None, repeat: int = 5) -> float:
    """Best of ``repeat`` runs of the whole scenario in C (initialisation not included),
    seconds per macro step."""
    loop = NativeMonolithic(scenario, None, fmu_dir)
    n = round(scenario.stop_time / loop.step)
    best = float("inf")
    for _ in range(repeat):
        loop.reset()
        t0 = time.perf_counter()
        loop.run(n)
        best = min(best, (time.perf_counter() - t0) / n)
    return best
