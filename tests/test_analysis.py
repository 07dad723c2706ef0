"""Linear analysis: equilibrium, eigenvalues, the paper's reduced-model test, sampled
loops, observer, stable K_c ranges."""

from __future__ import annotations

import contextlib
import io
import json
import math

import numpy as np
import pytest

from glider_cosim.studies.analysis import (
    analyze,
    closed_loop_matrix,
    format_report,
    observer_analysis,
    reduced_model_test,
    sampled_loop_eigenvalues,
    stable_kc_range,
    time_scales,
)
from glider_plant.params import GliderParams

P = GliderParams()


#: what ``analyze()`` wrote on stderr (a file: plain progress lines), for the test below
SHOWN: list[str] = []


@pytest.fixture(scope="module")
def result():
    with contextlib.redirect_stderr(io.StringIO()) as err:
        found = analyze()
    SHOWN.append(err.getvalue())
    return found


def test_analyze_shows_its_steps(result):
    """``glider-cosim analyze`` takes about 3 s: its steps show as they start (issue 45)."""
    assert SHOWN[0].splitlines() == [
        "analyze: the closed loop at 9 gains K_c (1 of 4)",
        "analyze: the stable K_c ranges at K_Fdelta = 29.5 (the model's) (2 of 4)",
        "analyze: the stable K_c ranges at K_Fdelta = 15 (3 of 4)",
        "analyze: the stable K_c ranges at K_Fdelta = 45 (4 of 4)",
    ]


def test_each_case_is_computed_once(monkeypatch):
    """The model's K_Fdelta (29.5) is one of the sensitivity study's: computed once."""
    from glider_cosim.studies import analysis

    seen = []
    real = analysis.stable_kc_ranges
    monkeypatch.setattr(analysis, "stable_kc_ranges",
                        lambda p, *a, **k: seen.append(p.K_Fdelta) or real(p, *a, **k))  # fmt: skip
    with contextlib.redirect_stderr(io.StringIO()):
        found = analyze(K_c_list=[10.0])
    assert sorted(seen) == [15.0, 29.5, 45.0]
    model = found["stable_K_c"]
    assert found["K_Fdelta_sensitivity"]["29.5"] == {k: model[k] for k in ("continuous", "sampled")}


def test_the_table_explains_its_columns(result):
    text = format_report(result)
    header = next(line for line in text.splitlines() if line.lstrip().startswith("K_c "))
    legend = text.split("\ncolumns:\n", 1)[1].splitlines()
    named = [line.split(": ", 1)[0].strip() for line in legend]
    assert named[:6] == ["K_c", "cont. max Re", "A22", "Schur", "|z| sampled", "|z| +observer"]
    for name in named[:6]:
        assert name in header
    assert "a larger K_c is gentler" in legend[0] and "Schur complement" in legend[3]


def test_json_object_with_the_contract_keys(result):
    data = json.loads(json.dumps(result))
    assert set(data["equilibrium"]) == {"V", "theta_g", "alpha", "omega2"}
    assert data["equilibrium"]["V"] == pytest.approx(0.2371273, abs=1e-7)
    for key in ("continuous", "sampled"):
        lo, hi = data["stable_K_c"][key]
        assert hi is None and lo > 0


def test_open_loop_is_stable_with_a_slow_phugoid():
    ev = np.linalg.eigvals(closed_loop_matrix(P, None))
    assert np.all(ev.real < 0)
    slow = ev[np.argmax(ev.real)]
    assert slow.real == pytest.approx(-0.0916, abs=1e-3)
    assert abs(slow.imag) == pytest.approx(0.2329, abs=1e-3)


def test_continuous_stability_boundary(result):
    lo, hi = result["stable_K_c"]["continuous"]
    assert 5.1 < lo < 5.4 and hi is None
    assert np.linalg.eigvals(closed_loop_matrix(P, 2.0)).real.max() > 0.5  # paper's K_c
    assert np.linalg.eigvals(closed_loop_matrix(P, 10.0)).real.max() < -0.1


def test_paper_reduced_model_test_passes_where_the_full_model_is_unstable():
    """Sec. 3.2's test holds 'for sufficiently small mu'; here mu = 0.14 and the test
    passes at K_c = 2 although the full linearisation is unstable."""
    t = reduced_model_test(P, 2.0)
    assert t["A22_hurwitz"] and t["schur_hurwitz"]
    assert t["mu"] == pytest.approx(time_scales(P)["mu"]) and t["mu"] > 0.1
    full = np.array([complex(*z) for z in t["full_nondimensional_eigenvalues"]])
    assert full.real.max() > 0


def test_sampled_loop_tends_to_the_continuous_loop_for_small_steps():
    k = 10.0
    cont = np.linalg.eigvals(closed_loop_matrix(P, k)).real.max()
    z = sampled_loop_eigenvalues(P, k, h=0.001, tau_servo=0.0005)
    rate = math.log(np.abs(z).max()) / 0.001
    assert rate == pytest.approx(cont, abs=0.01)


def test_sampled_loop_needs_a_larger_gain_than_the_continuous_one(result):
    assert result["stable_K_c"]["sampled"][0] > result["stable_K_c"]["continuous"][0]
    z = sampled_loop_eigenvalues(P, 10.0, observer=True)
    assert np.abs(z).max() < 1.0


def test_observer_is_observable_and_its_error_dynamics_stable():
    o = observer_analysis(P)
    assert o["observable"] and o["observability_rank"] == 4
    assert max(re for re, _ in o["error_eigenvalues"]) < -0.5


def test_stable_range_search_on_a_known_boundary():
    assert stable_kc_range(lambda k: k > 3.0) == [pytest.approx(3.0, rel=1e-6), None]
    assert stable_kc_range(lambda k: False) == [None, None]


def test_k_fdelta_sensitivity_moves_the_boundary(result):
    s = result["K_Fdelta_sensitivity"]
    lows = [s[k]["continuous"][0] for k in ("15", "29.5", "45")]
    assert lows[0] < lows[1] < lows[2]


def test_paper_dominant_terms_differ_from_the_schur_complement():
    t = reduced_model_test(P, 2.0)
    (b1, b2), (b3, b4) = t["schur_matrix"]
    (p1, p2), (p3, p4) = t["paper_dominant_terms"]
    assert p2 < 0 < p3 and b2 > 0 > b3  # opposite signs to the paper's argument
    assert abs(b4) > 100 * abs(p4)
    assert p4 == pytest.approx(-1.0, abs=1e-9)


def test_closed_loop_from_an_exact_jacobian_matches_central_differences():
    """The path analyze --from-fmu takes (a plant Jacobian given, the passivity law's exact
    gradient), fed the model's own exact Jacobian: every matrix within 1e-8 of the central
    differences', every eigenvalue within 1e-9, for each K_Fdelta studied."""
    from glider_cosim.studies.analysis import K_C_LIST, closed_loop_matrix
    from glider_plant.jacobian import plant_jacobian
    from glider_plant.model import equilibrium

    def exact(p):
        e = equilibrium(p)
        J = np.array(plant_jacobian((e.V, e.theta_g, e.alpha, 0.0, 0.0, 0.0), 0.0, 0.0,
                                    (0.0, 0.0, 0.0), p, 0.01, 1.0))  # fmt: skip
        return J[:4, :4], J[:4, 6]

    for kf in (15.0, 29.5, 45.0):
        p = GliderParams(K_Fdelta=kf)
        for k in (None, *K_C_LIST):
            old, new = closed_loop_matrix(p, k), closed_loop_matrix(p, k, exact)
            assert np.max(np.abs(new - old)) < 1e-8, (kf, k)
            ev_old = np.sort_complex(np.linalg.eigvals(old))
            assert np.max(np.abs(np.sort_complex(np.linalg.eigvals(new)) - ev_old)) < 1e-9
