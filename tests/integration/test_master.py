"""The master on small FMUs written for the test, with known analytic results."""

from __future__ import annotations

import numpy as np
import pytest

from glider_cosim.master import CoSimulation, System, SystemSpecError
from glider_cosim.runner.recorders import ArrayRecorder

pytestmark = pytest.mark.integration
H = 0.1


def run(system: System, coupling: str = "gauss-seidel", stop: float = 1.0, step: float = H):
    sim = CoSimulation(system, step=step, coupling=coupling)
    rec = ArrayRecorder()
    try:
        sim.run(stop, rec)
    finally:
        sim.close()
    return {c: rec.array()[:, i] for i, c in enumerate(rec.columns)}


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_integrator_of_a_constant_is_exact(test_fmus, coupling):
    sys_ = System(
        fmus={"i": test_fmus["MasterTestIntegrator"]},
        connections=[],
        parameters={"i": {"y0": 1.5}},
        driven={"i.u": 2.0},
    )
    r = run(sys_, coupling, stop=2.0)
    t = np.arange(21) * H
    np.testing.assert_allclose(r["time"], t, rtol=0, atol=1e-15)  # t0 + k*h, no drift
    np.testing.assert_allclose(r["i.y"], 1.5 + 2.0 * t, rtol=0, atol=1e-12)


def chain(test_fmus):
    """integrator(u=1) -> gain(k=3) -> delay."""
    return System(
        fmus={
            "i": test_fmus["MasterTestIntegrator"],
            "g": test_fmus["MasterTestGain"],
            "d": test_fmus["MasterTestDelay"],
        },
        connections=[("i.y", "g.u"), ("g.y", "d.u")],
        parameters={"g": {"k": 3.0}},
        driven={"i.u": 1.0},
    )


def test_gauss_seidel_feedthrough_acts_at_the_same_point(test_fmus):
    r = run(chain(test_fmus), "gauss-seidel")
    t = r["time"]
    np.testing.assert_allclose(r["g.y"], 3.0 * t, atol=1e-12)  # no delay through the gain
    np.testing.assert_allclose(r["d.y"][1:], 3.0 * t[:-1], atol=1e-12)  # one step of delay


def test_jacobi_feedthrough_sees_the_previous_point(test_fmus):
    r = run(chain(test_fmus), "jacobi")
    t = r["time"]
    # the gain is read before its input is updated: one sample late
    np.testing.assert_allclose(r["g.y"][1:], 3.0 * t[:-1], atol=1e-12)
    np.testing.assert_allclose(r["d.y"][2:], 3.0 * t[:-2], atol=1e-12)


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_feedback_loop_matches_the_discrete_map(test_fmus, coupling):
    """x' = -a x closed through a feedthrough gain: Euler-like maps of each scheme."""
    a = 2.0
    sys_ = System(
        fmus={"i": test_fmus["MasterTestIntegrator"], "g": test_fmus["MasterTestGain"]},
        connections=[("i.y", "g.u"), ("g.y", "i.u")],
        parameters={"i": {"y0": 1.0}, "g": {"k": -a}},
    )
    r = run(sys_, coupling, stop=2.0)
    n = len(r["time"])
    x = np.empty(n)
    x[0] = 1.0
    if coupling == "gauss-seidel":  # x_{k+1} = (1 - a h) x_k
        for k in range(n - 1):
            x[k + 1] = (1 - a * H) * x[k]
    else:  # the gain output read at t_k reflects x_{k-1}: x_{k+1} = x_k - a h x_{k-1}
        x[1] = x[0]  # at t0 the gain input still holds its start value 0
        for k in range(1, n - 1):
            x[k + 1] = x[k] - a * H * x[k - 1]
    np.testing.assert_allclose(r["i.y"], x, rtol=0, atol=1e-12)


def test_unknown_variable(test_fmus):
    sys_ = System(fmus={"i": test_fmus["MasterTestIntegrator"]}, connections=[("i.yy", "i.u")])
    with pytest.raises(
        SystemSpecError,
        match=r"instance i \(MasterTestIntegrator\) has no "
        r"variable 'yy'",
    ):
        CoSimulation(sys_).load()


def test_unknown_instance(test_fmus):
    sys_ = System(fmus={"i": test_fmus["MasterTestIntegrator"]}, connections=[("x.y", "i.u")])
    with pytest.raises(SystemSpecError, match=r"'x.y': no instance 'x' \(instances: i\)"):
        CoSimulation(sys_).load()


def test_type_mismatch(test_fmus):
    sys_ = System(
        fmus={"i": test_fmus["MasterTestIntegrator"], "g": test_fmus["MasterTestGain"]},
        connections=[("g.count", "i.u"), ("i.y", "g.u")],
    )
    with pytest.raises(SystemSpecError, match=r"g.count -> i.u: type mismatch \(Integer -> Real\)"):
        CoSimulation(sys_).load()


def test_input_left_unconnected(test_fmus):
    sys_ = System(fmus={"i": test_fmus["MasterTestIntegrator"]}, connections=[])
    with pytest.raises(SystemSpecError, match=r"input i.u is left unconnected"):
        CoSimulation(sys_).load()


def test_wrong_causality_and_bad_settings(test_fmus, tmp_path):
    sys_ = System(fmus={"i": test_fmus["MasterTestIntegrator"]}, connections=[("i.u", "i.u")])
    with pytest.raises(SystemSpecError, match=r"i.u has causality input: expected one of output"):
        CoSimulation(sys_).load()
    with pytest.raises(SystemSpecError, match=r"coupling 'sideways' is unknown"):
        CoSimulation(sys_, coupling="sideways")
    with pytest.raises(SystemSpecError, match=r"step = 0.0 is invalid"):
        CoSimulation(sys_, step=0.0)
    missing = System(fmus={"i": tmp_path / "nope.fmu"}, connections=[])
    with pytest.raises(SystemSpecError, match=r"nope.fmu does not exist"):
        CoSimulation(missing).load()
    junk = tmp_path / "junk.fmu"
    junk.write_text("not a zip")
    with pytest.raises(SystemSpecError, match=r"junk.fmu' is not a readable zip"):
        CoSimulation(System(fmus={"i": junk}, connections=[])).load()


def test_algebraic_loop_is_refused(test_fmus):
    sys_ = System(
        fmus={"a": test_fmus["MasterTestGain"], "b": test_fmus["MasterTestGain"]},
        connections=[("a.y", "b.u"), ("b.y", "a.u")],
    )
    with pytest.raises(SystemSpecError, match=r"algebraic loop"):
        CoSimulation(sys_).load()


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_c_loop_equals_the_python_loop_bit_for_bit(fmu_dir, coupling, monkeypatch):
    """The per-step calls made from C (glider_cosim.master.fastloop) and from Python."""
    from glider_cosim.scenarios.scenario import load_scenario
    from glider_cosim.scenarios.system import system_for

    def run_default() -> tuple[np.ndarray, bool]:
        sim = CoSimulation(system_for(load_scenario("default"), fmu_dir), coupling=coupling)
        rec = ArrayRecorder()
        try:
            sim.run(20.0, rec)
            fast = sim._fast is not None
        finally:
            sim.close()
        return rec.array(), fast

    c_data, c_fast = run_default()
    monkeypatch.setenv("GLIDER_COSIM_FASTLOOP", "0")
    py_data, py_fast = run_default()
    assert c_fast and not py_fast
    assert c_data.shape == py_data.shape == (1001, c_data.shape[1])
    assert np.array_equal(c_data, py_data)


def test_initialize_then_run_instantiates_once_and_a_second_run_frees_the_first(
    flavor_dir, monkeypatch
):
    """``initialize()`` then ``run()`` (what a host timing the run alone does) makes each
    instance once; a second ``run()`` frees the first run's instances, then starts afresh:
    the same rows."""
    from glider_cosim.master.instance import Instance
    from glider_cosim.scenarios.scenario import load_scenario
    from glider_cosim.scenarios.system import system_for

    made, freed = [], []
    instantiate, free = Instance.instantiate, Instance.free

    def counted_instantiate(self, *args):
        made.append(self.name)
        return instantiate(self, *args)

    def counted_free(self):
        if self.alive:
            freed.append(self.name)
        return free(self)

    monkeypatch.setattr(Instance, "instantiate", counted_instantiate)
    monkeypatch.setattr(Instance, "free", counted_free)
    sim = CoSimulation(system_for(load_scenario("default"), flavor_dir))
    try:
        sim.initialize()
        first, second = ArrayRecorder(), ArrayRecorder()
        sim.run(4.0, first)
        assert sorted(made) == sorted(sim.instances) and freed == []
        sim.run(4.0, second)
        assert sorted(freed) == sorted(sim.instances)  # the first run's, before the new
        assert len(made) == 2 * len(sim.instances)
    finally:
        sim.close()
    assert first.array().shape == (201, len(first.columns))
    assert np.array_equal(first.array(), second.array())
