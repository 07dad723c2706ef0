"""Initialization Mode as the strictest importers read it (issue 46), through fmpy's raw FMI
calls (``FMU2Slave``, ``FMU3Slave``), as a foreign importer makes them:

- every initial unknown of all 12 FMUs (3 components x 2 flavors x FMI 2.0 and 3.0) can be
  got between Enter and Exit: computed from the parameters, start values and inputs set
  so far, bit for bit the value after Exit;
- the ``dependencies`` of ``<InitialUnknowns>`` (FMI 3: ``<InitialUnknown>``) are true:
  changing a known that is not listed changes nothing, changing each listed one changes
  the unknown (in one of a few named settings, e.g. the seed only with noise on); the
  ``<Outputs>`` ones too, after Exit (the plant's outputs do not depend on its inputs at
  the same instant, the controller's command does);
- both attributes are written, ``dependenciesKind`` too, and fmpy's validation and the
  toolbox's checker stay clean.
"""

from __future__ import annotations

import logging
import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

pytestmark = pytest.mark.integration
NAMES = ("GliderPlant", "GliderObserver", "GliderController")
SETS = [(flavor, fmi) for fmi in (2, 3) for flavor in ("python", "native")]


@pytest.fixture(scope="module")
def fmu_sets(request) -> dict[tuple[str, int], Path]:
    """(flavor, FMI version) -> the folder of the three FMUs."""
    dirs3 = request.getfixturevalue("fmi3_dirs")
    return {
        ("python", 2): request.getfixturevalue("fmu_dir"),
        ("native", 2): request.getfixturevalue("native_dir"),
        ("python", 3): dirs3["python"],
        ("native", 3): dirs3["native"],
    }


class Importer:
    """One instance of an FMU through fmpy's raw FMI calls, values by variable name."""

    def __init__(self, fmu: Path, folder: Path, name: str = "a"):
        self.md = read_model_description(str(fmu))
        self.fmi3 = self.md.fmiVersion.startswith("3")
        folder = folder / f"{fmu.stem}_{name}_{'fmi3' if self.fmi3 else 'fmi2'}"
        if not folder.is_dir():
            with zipfile.ZipFile(fmu) as z:
                z.extractall(folder)
        self.vars = {v.name: v for v in self.md.modelVariables}
        cls = FMU3Slave if self.fmi3 else FMU2Slave
        self.s = cls(
            guid=self.md.guid,
            unzipDirectory=str(folder),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.s.instantiate()

    def kind(self, name: str) -> str:
        t = self.vars[name].type
        return {"Float64": "Real", "Int32": "Integer"}.get(t, t)

    def get(self, names: list[str]) -> list[float]:
        out = []
        for n in names:  # one call per variable: each is a get of its own in the mode
            vr, kind = [self.vars[n].valueReference], self.kind(n)
            if kind == "Real":
                out += (self.s.getFloat64 if self.fmi3 else self.s.getReal)(vr)
            elif kind == "Integer":
                out += (self.s.getInt32 if self.fmi3 else self.s.getInteger)(vr)
            else:
                out += [float(b) for b in self.s.getBoolean(vr)]
        return out

    def get_all(self, names: list[str]) -> list[float]:
        """The Real unknowns ``names`` in one call."""
        vrs = [self.vars[n].valueReference for n in names]
        return list((self.s.getFloat64 if self.fmi3 else self.s.getReal)(vrs))

    def set(self, values: dict[str, Any]) -> None:
        for n, value in values.items():
            vr, kind = [self.vars[n].valueReference], self.kind(n)
            if kind == "Real":
                (self.s.setFloat64 if self.fmi3 else self.s.setReal)(vr, [float(value)])
            elif kind == "Integer":
                (self.s.setInt32 if self.fmi3 else self.s.setInteger)(vr, [int(value)])
            else:
                self.s.setBoolean(vr, [bool(value)])

    def enter(self) -> None:
        if self.fmi3:
            self.s.enterInitializationMode(startTime=0.0)
        else:
            self.s.setupExperiment(startTime=0.0)
            self.s.enterInitializationMode()

    def close(self) -> None:
        self.s.freeInstance()


def initial_unknowns(md) -> list[str]:
    return [u.variable.name for u in md.initialUnknowns]


def inputs(md) -> list[str]:
    return [v.name for v in md.modelVariables if v.causality == "input"]


def start(v) -> float:
    s = v.start
    if v.type == "Boolean":
        return float(s in (True, "true", "1"))
    return float(s) if s is not None else 0.0


@pytest.mark.parametrize("flavor,fmi", SETS)
@pytest.mark.parametrize("name", NAMES)
def test_initial_unknowns_in_initialization_mode_equal_those_after_exit(
    fmu_sets, tmp_path, flavor, fmi, name
):
    fmu = fmu_sets[flavor, fmi] / f"{name}.fmu"
    imp = Importer(fmu, tmp_path)
    unknowns = initial_unknowns(imp.md)
    assert unknowns  # every output of ours is an initial unknown
    try:
        imp.enter()
        first = imp.get(unknowns)
        # the inputs set as an importer sets them from their sources: away from their
        # start values, so that a value computed before they were set would differ
        imp.set({n: start(imp.vars[n]) + 0.01 for n in inputs(imp.md)})
        in_mode = imp.get(unknowns)
        in_mode_batched = imp.get_all(unknowns)
        imp.s.exitInitializationMode()
        after = imp.get(unknowns)
    finally:
        imp.close()
    assert in_mode == after  # bit for bit
    assert in_mode_batched == after
    assert all(math.isfinite(v) for v in after)
    # the values are the model's, not zeros: e.g. the plant's pitch -35 + 1 deg
    nonzero = {"GliderPlant": "theta_meas", "GliderObserver": "V_hat"}
    if name in nonzero:
        i = unknowns.index(nonzero[name])
        assert first[i] != 0.0 and in_mode[i] == after[i]
    if name == "GliderObserver":  # the pre-filter passes the input set in the mode on
        i = unknowns.index("theta_filt")
        assert first[i] == start(imp.vars["theta_meas"])
        assert after[i] == start(imp.vars["theta_meas"]) + 0.01
    if name == "GliderController":  # the law acts on the inputs set in the mode
        assert first != in_mode


def test_a_parameter_refused_in_initialization_mode_is_an_error_naming_it(fmu_sets, tmp_path):
    # the same refusal as at Exit, when an initial unknown is got
    for (flavor, fmi), folder in fmu_sets.items():
        log: list[str] = []
        imp = Importer(folder / "GliderPlant.fmu", tmp_path, "refused")
        try:
            imp.enter()
            imp.set({"delta_0": 0.5, "delta_max": 0.25})
            with pytest.raises(Exception) as err:  # fmpy raises FMICallException
                imp.get(["theta"])
            log.append(str(err.value))
            assert type(err.value).__name__ == "FMICallException", (flavor, fmi)
        finally:
            imp.close()


# ---------------------------------------------------------------- dependencies
#: settings in which a known can show its effect (beside the FMU's defaults): the seed
#: only with noise on, *_hat_0 only without the equilibrium start (and the switch only
#: with *_hat_0 away from the equilibrium), the P gain under the P law, delta_open under
#: the open loop, delta_max when the command saturates, the law's inputs away from the
#: equilibrium; the plant's state derivatives: the tail's constants with the tail
#: deflected, K_q with a pitch rate, its delta_max with the command beyond it
SETTINGS = {
    "GliderPlant": [
        {},
        {"noise_std": 0.01},
        {"delta_0": 0.1, "omega2_0": 0.1},
        {"delta_cmd": 2.0},
    ],  # fmt: skip
    "GliderObserver": [
        {},
        {"start_at_equilibrium": False},
        {"V_hat_0": 0.3, "theta_g_hat_0": -0.5, "alpha_hat_0": 0.05, "omega2_hat_0": 0.1},
    ],
    "GliderController": [
        {},
        {"V_hat": 0.3, "theta_g_hat": -0.5},
        {"V_hat": 0.3, "theta_g_hat": -0.5, "law": 2},
        {"law": 0, "delta_open": 0.1},
        {"V_hat": 0.3, "theta_g_hat": -0.5, "delta_open": 0.1},
        {"law": 0, "delta_open": 1.0, "delta_max": 0.5},
    ],
}


def knowns(md) -> list[str]:
    """What an initial unknown may depend on (FMI 2.0.4 Sec. 2.2.8): the inputs and the
    variables with initial exact (our parameters)."""
    return [v.name for v in md.modelVariables if v.causality in ("input", "parameter")]


def changed(v, value: float) -> float:
    """Another valid value of ``v``, near ``value``."""
    if v.type == "Boolean":
        return 1.0 - value
    if v.type in ("Integer", "Int32"):
        high = float(v.max) if v.max is not None else math.inf
        return value + 1 if value + 1 <= high else value - 1
    return value * 1.05 if value != 0.0 else 0.05


def dependencies(md, group: str) -> dict[str, set[str]]:
    units = md.initialUnknowns if group == "initial" else md.outputs
    out = {}
    for u in units:
        assert u.dependencies is not None, (group, u.variable.name)  # written
        assert u.dependenciesKind is not None and len(u.dependenciesKind) == len(u.dependencies)
        out[u.variable.name] = {d.name for d in u.dependencies}
    return out


@pytest.mark.parametrize("flavor,fmi", SETS)
@pytest.mark.parametrize("name", NAMES)
def test_initial_unknowns_depend_on_exactly_the_listed_knowns(
    fmu_sets, tmp_path, flavor, fmi, name
):
    fmu = fmu_sets[flavor, fmi] / f"{name}.fmu"
    imp = Importer(fmu, tmp_path)
    deps = dependencies(imp.md, "initial")
    unknowns = list(deps)
    shown: dict[str, set[str]] = {u: set() for u in unknowns}
    try:
        imp.enter()
        base_values = {n: start(imp.vars[n]) for n in knowns(imp.md)}
        for setting in SETTINGS[name]:
            base = {**base_values, **setting}
            imp.set(base)
            ref = imp.get(unknowns)
            for known in knowns(imp.md):
                imp.set({known: changed(imp.vars[known], base[known])})
                got = imp.get(unknowns)
                imp.set({known: base[known]})
                for i, u in enumerate(unknowns):
                    if got[i] != ref[i]:
                        assert known in deps[u], f"{u} changes with {known}, not listed"
                        shown[u].add(known)
            imp.set(base_values)
    finally:
        imp.close()
    for u in unknowns:  # every listed known shows its effect in one of the settings
        assert shown[u] == deps[u], (u, sorted(deps[u] - shown[u]))


@pytest.mark.parametrize("flavor,fmi", SETS)
@pytest.mark.parametrize("name", NAMES)
def test_outputs_depend_on_exactly_the_listed_inputs(fmu_sets, tmp_path, flavor, fmi, name):
    # after Exit (and after a step): an input set now shows in an output now only if it
    # is listed: the controller's command does, no output of the plant or observer does
    fmu = fmu_sets[flavor, fmi] / f"{name}.fmu"
    imp = Importer(fmu, tmp_path)
    deps = dependencies(imp.md, "outputs")
    outs = list(deps)
    ins = inputs(imp.md)
    expected = {"GliderController": {"delta_cmd": {"V_hat", "theta_g_hat"}}}.get(name, {})
    assert deps == {o: expected.get(o, set()) for o in outs}
    try:
        imp.enter()
        imp.s.exitInitializationMode()
        for stepped in (False, True):
            if stepped:
                imp.s.doStep(0.0, 0.02)
            ref = imp.get(outs)
            for known in ins:
                value = imp.get([known])[0]
                imp.set({known: value + 0.05})
                got = imp.get(outs)
                imp.set({known: value})
                for i, o in enumerate(outs):
                    assert (got[i] != ref[i]) == (known in deps[o]), (o, known, stepped)
    finally:
        imp.close()


@pytest.mark.parametrize("flavor,fmi", SETS)
def test_model_descriptions_stay_valid(fmu_sets, flavor, fmi):
    for name in NAMES:
        fmu = fmu_sets[flavor, fmi] / f"{name}.fmu"
        assert validate_fmu(str(fmu)) == [], name
        verdicts = toolbox_check(fmu)
        assert [v for v in verdicts if v[0] != "INFO"] == [], (name, verdicts)
        assert f"No semantic error against the FMI-{fmi} standard." in {m for _, m in verdicts}


def toolbox_check(fmu: Path) -> list[tuple[str, str]]:
    """What fmu-manipulation-toolbox's checkers (``fmutool -check``) log on an FMU:
    (level, message)."""
    from fmu_manipulation_toolbox.checker import get_checkers
    from fmu_manipulation_toolbox.operations import FMU

    seen: list[tuple[str, str]] = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            seen.append((record.levelname, record.getMessage()))

    log = logging.getLogger("fmu_manipulation_toolbox")
    handler, level = Keep(), log.level
    log.addHandler(handler)
    log.setLevel(logging.INFO)
    try:
        toolbox_fmu = FMU(str(fmu))
        for checker in get_checkers():
            toolbox_fmu.apply_operation(checker())
    finally:
        log.removeHandler(handler)
        log.setLevel(level)
    return seen


# ---------------------------------------------------------------- one t = 0
COUPLINGS = ("gauss-seidel", "jacobi")


def _rows(result) -> tuple[list[str], np.ndarray]:
    cols = [c for c in result.columns if c != "time"]
    return cols, np.array([result.column(c) for c in cols]).T


@pytest.mark.parametrize("flavor,fmi", SETS)
def test_the_master_sets_the_inputs_in_initialization_mode(fmu_sets, monkeypatch, flavor, fmi):
    # issue 46: observer theta_filt(0) is the measured pitch that the master set there
    # (not the observer's start value); the first row is the same in both couplings; every
    # row from the first step on is the one the master before gave (it set nothing in
    # the mode: _exit_only), bit for bit
    from glider_cosim.master.cosimulation import CoSimulation
    from glider_cosim.runner import simulate

    folder = fmu_sets[flavor, fmi]
    runs = {c: simulate(None, None, fmu_dir=folder, build=False, coupling=c, stop_time=5.0)
            for c in COUPLINGS}  # fmt: skip
    for c, r in runs.items():
        assert r.column("observer.theta_filt")[0] == r.column("plant.theta_meas")[0], c
        assert r.column("observer.theta_filt")[0] != -0.36751268161909123  # the start value
    cols, gs = _rows(runs["gauss-seidel"])
    assert np.array_equal(gs[0], _rows(runs["jacobi"])[1][0])
    monkeypatch.setattr(CoSimulation, "_initialization_mode", _exit_only)
    for c, r in runs.items():
        before = simulate(None, None, fmu_dir=folder, build=False, coupling=c, stop_time=5.0)
        _, old = _rows(before)
        _, new = _rows(r)
        assert np.array_equal(old[1:], new[1:]), c
        changed = [cols[i] for i in np.nonzero(old[0] != new[0])[0]]
        assert changed == ["observer.theta_filt"], (c, changed)


def _exit_only(sim) -> None:
    """The master before issue 46: every instance exits Initialization Mode, nothing set."""
    for inst in sim.instances.values():
        sim._exit(inst)


def test_the_initialization_order_follows_the_dependencies(fmu_dir):
    # the plant's outputs first (they depend on none of its inputs), then the observer's
    # pitch, then the estimate to the controller, then its command to the plant and the
    # observer; a loop is cut at its first input in the declared order
    from glider_cosim.master.cosimulation import CoSimulation
    from glider_cosim.master.plan import initialization_order
    from glider_cosim.scenarios.scenario import load_scenario
    from glider_cosim.scenarios.system import system_for

    sim = CoSimulation(system_for(load_scenario(None), fmu_dir))
    sim.load()
    order = [dst for dst, _ in sim._init_order]
    assert order.index("observer.theta_meas") < order.index("controller.V_hat")
    assert order.index("controller.theta_g_hat") < order.index("plant.delta_cmd")
    assert order.index("controller.theta_g_hat") < order.index("observer.delta_cmd")
    assert sim.initialization_cut == []
    # without declared dependencies (every input counts), the loop is cut
    for inst in sim.instances.values():
        inst.initial_inputs = dict.fromkeys(inst.initial_inputs)
    order, cut = initialization_order(sim.instances, sim._sources, [])
    assert cut and len(order) == len(sim._sources)
