"""Dense continuous-time algebraic Riccati solver in plain Python (floats, lists, ``math``).

Solves the filter form of the observer's Eq. (36),

    A P + P A^T + Q - P G P = 0,   G = C^T C / R,

for the stabilizing solution ``P`` (``A - P G`` Hurwitz, ``P`` symmetric positive definite).
It replaces scipy's ``solve_continuous_are`` so that the FMUs need no numpy/scipy at run
time; ``observer_model.c`` is its C twin, written operation by operation in the same order
so that both give the same bits on linux64.

Algorithm (deterministic, no initial guess needed):

1. Matrix sign function of the Hamiltonian ``Z0 = [[A^T, -G], [-Q, -A]]`` by the Newton
   iteration ``Z <- (Z / c + c Z^-1) / 2`` with determinant scaling ``c = |det Z|^(1/2n)``
   while the relative 1-norm change exceeds 1e-2, unscaled (``c = 1``) afterwards; it stops
   when the relative 1-norm change is <= 1e-10 (at most ``SIGN_MAX_ITER`` steps).
2. ``P0`` from the stable invariant subspace: ``[W12; W22 + I] P = -[W11 + I; W21]`` in the
   least-squares sense (normal equations), symmetrized.
3. Newton-Kleinman refinement in correction form: ``(A - P G) D + D (A - P G)^T = -Res(P)``,
   ``P <- sym(P + D)``, each Lyapunov equation solved as a Kronecker system by Gaussian
   elimination with partial pivoting. It stops one step after the first step with
   ``max|D| <= 1e-13 max|P|`` (the final refinement step), at most ``NEWTON_MAX_ITER``
   steps.
4. ``P`` must be positive definite (Cholesky), which with ``Q > 0`` proves ``A - P G``
   Hurwitz.

Failures raise :class:`RiccatiError` (a ``ParameterError``) with a message saying which
stage failed.
"""

from __future__ import annotations

import math

from glider_plant.params import ParameterError

SIGN_MAX_ITER = 100
SIGN_SCALE_TOL = 1e-2
SIGN_TOL = 1e-10
NEWTON_MAX_ITER = 30
NEWTON_TOL = 1e-13

Matrix = list[list[float]]


class RiccatiError(ParameterError):
    """The Riccati equation has no stabilizing solution that the solver could find."""


def _zeros(n: int, m: int) -> Matrix:
    return [[0.0] * m for _ in range(n)]


def _matmul(A: Matrix, B: Matrix) -> Matrix:
    n, k, m = len(A), len(B), len(B[0])
    out = _zeros(n, m)
    for i in range(n):
        for j in range(m):
            s = 0.0
            for l in range(k):
                s += A[i][l] * B[l][j]
            out[i][j] = s
    return out


def _transpose(A: Matrix) -> Matrix:
    return [[A[j][i] for j in range(len(A))] for i in range(len(A[0]))]


def _norm1(A: Matrix) -> float:
    """Largest column sum of absolute values."""
    best = 0.0
    for j in range(len(A[0])):
        s = 0.0
        for i in range(len(A)):
            s += abs(A[i][j])
        if s > best:
            best = s
    return best


def _maxabs(A: Matrix) -> float:
    best = 0.0
    for row in A:
        for a in row:
            if abs(a) > best:
                best = abs(a)
    return best


def _eliminate(M: Matrix, B: Matrix) -> tuple[Matrix, float] | None:
    """``M X = B`` by Gaussian elimination with partial pivoting: ``X`` and ``log|det
    M|``; None if singular. ``M`` (n x n) and ``B`` (n x m) are overwritten."""
    n, m = len(M), len(B[0])
    logdet = 0.0
    for k in range(n):
        p = k
        best = abs(M[k][k])
        for i in range(k + 1, n):
            if abs(M[i][k]) > best:
                best = abs(M[i][k])
                p = i
        if not best > 0.0 or not math.isfinite(best):
            return None
        logdet += math.log(best)
        if p != k:
            M[k], M[p] = M[p], M[k]
            B[k], B[p] = B[p], B[k]
        piv = M[k][k]
        for i in range(k + 1, n):
            f = M[i][k] / piv
            if f != 0.0:
                for j in range(k + 1, n):
                    M[i][j] -= f * M[k][j]
                for j in range(m):
                    B[i][j] -= f * B[k][j]
    X = _zeros(n, m)
    for i in range(n - 1, -1, -1):
        for j in range(m):
            s = B[i][j]
            for l in range(i + 1, n):
                s -= M[i][l] * X[l][j]
            X[i][j] = s / M[i][i]
    return X, logdet


def _solve(M: Matrix, B: Matrix) -> Matrix | None:
    """``M X = B`` (:func:`_eliminate`); None if singular. ``M`` and ``B`` are
    overwritten."""
    solved = _eliminate(M, B)
    return None if solved is None else solved[0]


def _inverse_and_logdet(Z: Matrix) -> tuple[Matrix, float] | None:
    """``Z^-1`` and ``log|det Z|`` (one LU with partial pivoting); None if singular."""
    n = len(Z)
    return _eliminate([row[:] for row in Z], [[1.0 if i == j else 0.0 for j in range(n)]
                                              for i in range(n)])  # fmt: skip


def _residual(A: Matrix, P: Matrix, Q: Matrix, G: Matrix) -> Matrix:
    """``A P + P A^T + Q - P G P``."""
    AP = _matmul(A, P)
    PAT = _matmul(P, _transpose(A))
    PGP = _matmul(_matmul(P, G), P)
    n = len(A)
    return [[AP[i][j] + PAT[i][j] + Q[i][j] - PGP[i][j] for j in range(n)] for i in range(n)]


def _lyapunov(F: Matrix, M: Matrix) -> Matrix | None:
    """``X`` with ``F X + X F^T = M`` (Kronecker system, row-major unknowns)."""
    n = len(F)
    K = _zeros(n * n, n * n)
    for i in range(n):
        for j in range(n):
            r = n * i + j
            for l in range(n):
                K[r][n * l + j] += F[i][l]
                K[r][n * i + l] += F[j][l]
    b = [[M[i][j]] for i in range(n) for j in range(n)]
    x = _solve(K, b)
    if x is None:
        return None
    return [[x[n * i + j][0] for j in range(n)] for i in range(n)]


def _symmetrize(P: Matrix) -> Matrix:
    n = len(P)
    return [[0.5 * (P[i][j] + P[j][i]) for j in range(n)] for i in range(n)]


def _is_positive_definite(P: Matrix) -> bool:
    """Cholesky succeeds with positive pivots."""
    n = len(P)
    L = _zeros(n, n)
    for j in range(n):
        s = P[j][j]
        for k in range(j):
            s -= L[j][k] * L[j][k]
        if not s > 0.0 or not math.isfinite(s):
            return False
        d = math.sqrt(s)
        L[j][j] = d
        for i in range(j + 1, n):
            t = P[i][j]
            for k in range(j):
                t -= L[i][k] * L[j][k]
            L[i][j] = t / d
    return True


def _sign_initial(A: Matrix, Q: Matrix, G: Matrix) -> Matrix:
    """Stabilizing solution from the sign function of the Hamiltonian (steps 1-2)."""
    n = len(A)
    n2 = 2 * n
    Z = _zeros(n2, n2)
    for i in range(n):
        for j in range(n):
            Z[i][j] = A[j][i]
            Z[i][n + j] = -G[i][j]
            Z[n + i][j] = -Q[i][j]
            Z[n + i][n + j] = -A[i][j]
    scale = True
    converged = False
    for _ in range(SIGN_MAX_ITER):
        inv = _inverse_and_logdet(Z)
        if inv is None:
            raise RiccatiError(
                "the Hamiltonian matrix of the Riccati equation is singular "
                "(an eigenvalue on the imaginary axis)"
            )
        Zi, logdet = inv
        c = math.exp(logdet / n2) if scale else 1.0
        Zn = [[0.5 * (Z[i][j] / c + c * Zi[i][j]) for j in range(n2)] for i in range(n2)]
        D = [[Zn[i][j] - Z[i][j] for j in range(n2)] for i in range(n2)]
        change = _norm1(D)
        size = _norm1(Zn)
        Z = Zn
        if not math.isfinite(change) or not math.isfinite(size):
            break
        if change <= SIGN_TOL * size:
            converged = True
            break
        if change <= SIGN_SCALE_TOL * size:
            scale = False
    if not converged:
        raise RiccatiError(
            f"the sign iteration of the Riccati equation did not converge in "
            f"{SIGN_MAX_ITER} steps (no stabilizing solution?)"
        )
    # [W12; W22 + I] P = -[W11 + I; W21], least squares by the normal equations
    Mx = _zeros(n2, n)
    Nx = _zeros(n2, n)
    for i in range(n):
        for j in range(n):
            Mx[i][j] = Z[i][n + j]
            Mx[n + i][j] = Z[n + i][n + j] + (1.0 if i == j else 0.0)
            Nx[i][j] = -(Z[i][j] + (1.0 if i == j else 0.0))
            Nx[n + i][j] = -Z[n + i][j]
    MT = _transpose(Mx)
    P = _solve(_matmul(MT, Mx), _matmul(MT, Nx))
    if P is None:
        raise RiccatiError(
            "the stable invariant subspace of the Riccati equation is degenerate "
            "(no stabilizing solution)"
        )
    return _symmetrize(P)


def solve_filter_care(A: Matrix, Q: Matrix, G: Matrix) -> Matrix:
    """Stabilizing ``P`` of ``A P + P A^T + Q - P G P = 0`` (``Q``, ``G`` symmetric).

    Parameters
    ----------
    A, Q, G : list of lists of floats
        Square matrices of the same size.

    Returns
    -------
    list of lists of floats
        Symmetric positive definite ``P``.

    Raises
    ------
    RiccatiError
        If no stabilizing solution was found (see the module docstring's stages).
    """
    n = len(A)
    P = _sign_initial(A, Q, G)
    done = False
    final = False
    for _ in range(NEWTON_MAX_ITER):
        PG = _matmul(P, G)
        F = [[A[i][j] - PG[i][j] for j in range(n)] for i in range(n)]
        Res = _residual(A, P, Q, G)
        D = _lyapunov(F, [[-Res[i][j] for j in range(n)] for i in range(n)])
        if D is None:
            break
        P = _symmetrize([[P[i][j] + D[i][j] for j in range(n)] for i in range(n)])
        size = _maxabs(P)
        change = _maxabs(D)
        if not math.isfinite(size) or not math.isfinite(change):
            break
        if final:
            done = True
            break
        if change <= NEWTON_TOL * size:
            final = True  # one more step: the final refinement
    if not done:
        raise RiccatiError(
            f"the Newton refinement of the Riccati equation did not converge in "
            f"{NEWTON_MAX_ITER} steps"
        )
    if not _is_positive_definite(P):
        raise RiccatiError(
            "the Riccati solution is not positive definite (no stabilizing solution)"
        )
    return P
