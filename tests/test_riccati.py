"""The pure-Python Riccati solver (glider_observer.riccati) against scipy, and the import audit.

scipy is a test/analysis dependency only: the FMU packages (glider_plant, glider_observer,
glider_controller, glider_fmi) must import and compute the observer gain without numpy or
scipy.
"""

from __future__ import annotations

import itertools
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from scipy.linalg import solve_continuous_are

from glider_observer.model import C_O, linearization, observer_gain, riccati_solution
from glider_observer.riccati import RiccatiError, solve_filter_care
from glider_plant.params import GliderParams, ParameterError

R_GRID = (1e-4, 1e-3, 0.01, 0.1, 1.0, 10.0)
Q_VALUES = (1e-4, 0.01, 0.1, 1.0, 10.0)
#: uniform Q plus every fourth non-uniform combination of the Q values (deterministic)
Q_GRID = [(q,) * 4 for q in Q_VALUES] + [
    q for q in itertools.product(Q_VALUES, repeat=4) if len(set(q)) > 1
][::37]
PARAMS = (
    GliderParams(),
    GliderParams(m=12.0, J2=0.1),
    GliderParams(K_M0=0.2, K_D=200.0),
    GliderParams(K_q=-0.3, m0=0.2, K_L=250.0),
)
TOL = 1e-12


def _scipy(p: GliderParams, R: float, Q) -> tuple[np.ndarray, np.ndarray]:
    A = np.array(linearization(p))
    C = np.array([C_O])
    P = solve_continuous_are(A.T, C.T, np.diag(Q), np.array([[R]]))
    return P, (P @ C.T / R)[:, 0]


def _rel(x, ref) -> float:
    """Norm-wise relative difference max|x - ref| / max|ref|."""
    x, ref = np.asarray(x, dtype=float), np.asarray(ref, dtype=float)
    return float(np.max(np.abs(x - ref)) / np.max(np.abs(ref)))


@pytest.mark.parametrize("p", PARAMS, ids=["default", "m-J2", "KM0-KD", "Kq-m0-KL"])
def test_solver_matches_scipy_over_grid(p):
    assert len(Q_GRID) > 20
    worst_P = worst_H = 0.0
    for R in R_GRID:
        for Q in Q_GRID:
            P_ref, H_ref = _scipy(p, R, Q)
            P = riccati_solution(p, R, Q)
            H = observer_gain(p, R, Q)
            assert all(P[i][j] == P[j][i] for i in range(4) for j in range(4))
            worst_P = max(worst_P, _rel(P, P_ref))
            worst_H = max(worst_H, _rel(H, H_ref))
    assert worst_P <= TOL and worst_H <= TOL, (worst_P, worst_H)


def test_residual_is_at_rounding_level():
    p = GliderParams()
    A = np.array(linearization(p))
    C = np.array([C_O])
    for R, Q in ((0.1, (0.1,) * 4), (1e-4, (1e-4, 1e-4, 10.0, 10.0)), (10.0, (10.0, 1e-4, 1, 1))):
        P = np.array(riccati_solution(p, R, Q))
        res = A @ P + P @ A.T + np.diag(Q) - P @ C.T @ C @ P / R
        scale = np.max(np.abs(A @ P)) + np.max(np.abs(np.diag(Q)))
        assert np.max(np.abs(res)) <= 1e-13 * scale
        assert np.all(np.linalg.eigvals(A - P @ C.T @ C / R).real < 0.0)


def test_no_stabilizing_solution_raises():
    # eigenvalues +-i, unobservable: the Hamiltonian has imaginary-axis eigenvalues
    with pytest.raises(RiccatiError, match="Riccati"):
        solve_filter_care([[0.0, 1.0], [-1.0, 0.0]], [[1.0, 0.0], [0.0, 1.0]], [[0.0] * 2] * 2)
    # an unstable mode the measurement does not see (undetectable)
    with pytest.raises(RiccatiError, match="Riccati"):
        solve_filter_care([[1.0, 0.0], [0.0, -1.0]], [[1.0, 0.0], [0.0, 1.0]], [[0, 0], [0, 1.0]])
    assert issubclass(RiccatiError, ParameterError)


def test_invalid_weights_keep_their_messages():
    p = GliderParams()
    with pytest.raises(ParameterError, match=r"^R = 0\.0 is invalid: expected a finite value > 0$"):
        observer_gain(p, 0.0, (0.1,) * 4)
    with pytest.raises(ParameterError, match=r"^Q_alpha = nan is invalid"):
        observer_gain(p, 0.1, (0.1, 0.1, math.nan, 0.1))


AUDIT = textwrap.dedent(
    """
    import sys

    class Block:
        def find_spec(self, name, path=None, target=None):
            if name.partition(".")[0] in ("numpy", "scipy"):
                raise ImportError(f"{name} is not available in an FMU")
            return None

    sys.meta_path.insert(0, Block())
    import glider_plant.slave, glider_observer.slave, glider_controller.slave  # noqa
    import glider_fmi.slave_base, glider_fmi.state_codec  # noqa
    from glider_observer.model import observer_gain
    from glider_plant.params import GliderParams

    H = observer_gain(GliderParams(), 0.1, (0.1, 0.1, 0.1, 0.1))
    assert len(H) == 4 and all(isinstance(h, float) for h in H), H
    loaded = sorted(m for m in sys.modules if m.partition(".")[0] in ("numpy", "scipy"))
    assert not loaded, loaded
    print("ok")
    """
)


def test_fmu_packages_import_without_numpy_and_scipy():
    proc = subprocess.run(
        [sys.executable, "-c", AUDIT], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "ok"
