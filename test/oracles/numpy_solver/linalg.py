"""Test oracle (frozen numpy implementation, see __init__). Dense linear algebra on stacks of small square matrices (N, k, k), fast for N = 1 too.

numpy.linalg costs ~10 µs of Python overhead per call whatever the size, more than the
arithmetic of a 15×15 system; a live node solves one pose at a time, so a single matrix goes
straight to LAPACK (scipy's thin wrappers, ~1-3 µs). Stacks use numpy's batched routines.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack


def solve_square(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x (N, k) with a·x = b for b (N, k) and a (N, k, k), or a (1, k, k) shared by all N right-hand
    sides (one factorization); pseudo-inverse solution where a is singular."""
    if a.shape[0] == 1:
        _, _, x, info = lapack.dgesv(a[0], b.T)
        return x.T if info == 0 else b @ np.linalg.pinv(a[0]).T
    try:
        return np.linalg.solve(a, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return np.einsum("nij,nj->ni", np.linalg.pinv(a), b)


def det_sign_and_condition(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sign of det(a) (N,) (0 where singular) and 1-norm condition number (N,) (inf if singular)."""
    if a.shape[0] != 1:
        return np.linalg.slogdet(a)[0], inverse_and_condition(a)[1]
    lu, piv, info = lapack.dgetrf(a[0])   # one LU gives both
    if info > 0:
        return np.zeros(1), _condition_svd(a)
    # det = Π diag(U) · (−1)^(number of row swaps); scipy's pivots are 0-based
    swaps = np.count_nonzero(piv != np.arange(piv.size))
    sign = np.sign(np.diagonal(lu)).prod() * (-1.0) ** swaps
    inv, _ = lapack.dgetri(lu, piv)
    return np.array([sign]), _norm_1(a) * _norm_1(inv[None])


def inverse_and_condition(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse (N, k, k) (pseudo-inverse where singular) and 1-norm condition number (N,) (inf if singular)."""
    if a.shape[0] == 1:
        lu, piv, info = lapack.dgetrf(a[0])
        if info == 0:
            inv, info = lapack.dgetri(lu, piv)
        if info != 0:
            return np.linalg.pinv(a), _condition_svd(a)
        inv = inv[None]
    else:
        try:
            inv = np.linalg.inv(a)
        except np.linalg.LinAlgError:
            return np.linalg.pinv(a), _condition_svd(a)
    return inv, _norm_1(a) * _norm_1(inv)


def condition_1(a: np.ndarray) -> np.ndarray:
    """1-norm condition number (N,) of each square matrix in a stack (N, k, k); inf if singular."""
    return inverse_and_condition(a)[1]


def _norm_1(a: np.ndarray) -> np.ndarray:
    """Matrix 1-norm (largest absolute column sum) of each matrix in a stack."""
    return np.abs(a).sum(axis=1).max(axis=1)


def _condition_svd(a: np.ndarray) -> np.ndarray:
    """1-norm condition bound k·σ_max/σ_min (N,) for stacks containing singular matrices."""
    sv = np.linalg.svd(a, compute_uv=False)
    with np.errstate(divide="ignore"):
        return np.where(sv[:, -1] > 0, sv[:, 0] / sv[:, -1], np.inf) * a.shape[-1]
