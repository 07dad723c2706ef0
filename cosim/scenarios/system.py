"""The glider's closed loop as a master :class:`System`: which FMUs, how they connect,
what a scenario sets."""

from __future__ import annotations

from pathlib import Path

from ..master.spec import System
from .sampling import has_our_observer, with_sampling
from .scenario import Scenario, load_scenario

FMU_NAMES = {"plant": "GliderPlant", "observer": "GliderObserver", "controller": "GliderController"}


DISTURBANCE_INPUTS = ("plant.F_x", "plant.F_z", "plant.M_y")


def default_connections(feedback: str = "observer", observer: bool = True) -> list[tuple[str, str]]:
    """The closed loop: plant -> observer -> controller -> plant (and -> observer)."""
    conns = [("controller.delta_cmd", "plant.delta_cmd")]
    if observer:
        conns += [
            ("plant.theta_meas", "observer.theta_meas"),
            ("controller.delta_cmd", "observer.delta_cmd"),
        ]
    if feedback == "state":
        conns += [("plant.V", "controller.V_hat"), ("plant.theta_g", "controller.theta_g_hat")]
    else:
        conns += [
            ("observer.V_hat", "controller.V_hat"),
            ("observer.theta_g_hat", "controller.theta_g_hat"),
        ]
    return conns


def swapped(scenario: Scenario) -> set[str]:
    """Our FMUs (model identifiers) a run of ``scenario`` does not take from the FMU
    folder: the instances its ``[fmus]`` table swaps (neither built nor checked there)."""
    return {FMU_NAMES[inst] for inst in scenario.fmus}


def swapped_in(scenario: str | Path | None) -> set[str]:
    """:func:`swapped` of a scenario as a command names it (a TOML file, a shipped name,
    None: the default); an SSP brings its own FMUs: none."""
    if scenario is not None and str(scenario).endswith((".ssp", ".ssd")):
        return set()
    return swapped(load_scenario(scenario))


def system_for(scenario: Scenario, fmu_dir: Path, step: float | None = None) -> System:
    """The :class:`System` a scenario describes (FMUs from ``fmu_dir`` unless swapped),
    run at ``step`` (s; default the scenario's): the observer's ``f_sample`` follows it
    unless the scenario sets it (:func:`~glider_cosim.scenarios.sampling.with_sampling`)."""
    fmus = {
        inst: Path(scenario.fmus.get(inst, fmu_dir / f"{name}.fmu"))
        for inst, name in FMU_NAMES.items()
        if scenario.observer or inst != "observer"
    }
    driven = dict.fromkeys(DISTURBANCE_INPUTS, 0.0)
    driven.update(scenario.inputs)
    return System(
        fmus=fmus,
        connections=default_connections(scenario.feedback, scenario.observer),
        parameters=with_sampling(
            scenario.parameters,
            step if step is not None else scenario.step,
            scenario.source,
            has_our_observer(scenario),
        ),
        driven=driven,
        disturbances=list(scenario.disturbances),
        events=[type(e)(**{**e.__dict__}) for e in scenario.events],
        record=scenario.record,
    )
