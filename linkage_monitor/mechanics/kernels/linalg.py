"""Small dense linear algebra for the per-pose kernels: partial-pivoting LU, its solve and 1-norm
condition number, the determinant's sign, least squares by the normal equations, and the loop
closure's step (hinges closed, measured inputs fitted)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def lu_factor(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """LU of a square matrix (a copy): (lu, row permutation, number of row swaps, singular)."""
    k = a.shape[0]
    lu = a.copy()
    piv = np.arange(k)
    swaps = 0
    for j in range(k):
        p = j
        big = abs(lu[j, j])
        for i in range(j + 1, k):
            if abs(lu[i, j]) > big:
                big, p = abs(lu[i, j]), i
        if big == 0.0 or not math.isfinite(big):
            return lu, piv, swaps, True
        if p != j:
            for c in range(k):
                lu[j, c], lu[p, c] = lu[p, c], lu[j, c]
            piv[j], piv[p] = piv[p], piv[j]
            swaps += 1
        inv = 1.0 / lu[j, j]
        for i in range(j + 1, k):
            f = lu[i, j] * inv
            lu[i, j] = f
            if f != 0.0:
                for c in range(j + 1, k):
                    lu[i, c] -= f * lu[j, c]
    return lu, piv, swaps, False


@njit(cache=True)
def lu_solve(lu: np.ndarray, piv: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with a·x = b from ``lu_factor(a)``."""
    k = lu.shape[0]
    x = np.empty(k)
    for i in range(k):
        x[i] = b[piv[i]]
    for i in range(k):
        acc = x[i]
        for c in range(i):
            acc -= lu[i, c] * x[c]
        x[i] = acc
    for i in range(k - 1, -1, -1):
        acc = x[i]
        for c in range(i + 1, k):
            acc -= lu[i, c] * x[c]
        x[i] = acc / lu[i, i]
    return x


@njit(cache=True)
def norm_1(a: np.ndarray) -> float:
    """Matrix 1-norm: the largest absolute column sum."""
    best = 0.0
    for c in range(a.shape[1]):
        acc = 0.0
        for r in range(a.shape[0]):
            acc += abs(a[r, c])
        if acc > best:
            best = acc
    return best


@njit(cache=True)
def inverse_norm_1(lu: np.ndarray, piv: np.ndarray) -> float:
    """1-norm of a⁻¹ from ``lu_factor(a)``: L·U·X = P solved for all columns together, row operations
    over whole rows (independent columns: vectorized, no dependency chain along a column)."""
    k = lu.shape[0]
    x = np.zeros((k, k))
    for i in range(k):
        x[i, piv[i]] = 1.0
    for i in range(k):
        for j in range(i):
            f = lu[i, j]
            if f != 0.0:
                for c in range(k):
                    x[i, c] -= f * x[j, c]
    column_sum = np.zeros(k)
    for i in range(k - 1, -1, -1):
        for j in range(i + 1, k):
            f = lu[i, j]
            if f != 0.0:
                for c in range(k):
                    x[i, c] -= f * x[j, c]
        inv = 1.0 / lu[i, i]
        for c in range(k):
            x[i, c] *= inv
            column_sum[c] += abs(x[i, c])
    best = 0.0
    for c in range(k):
        if not column_sum[c] <= best:
            best = column_sum[c]
    return best


@njit(cache=True)
def factor_and_condition(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """LU of a square matrix (``lu_factor``) and its exact 1-norm condition number ‖a‖₁·‖a⁻¹‖₁ (inf when
    singular)."""
    lu, piv, _, singular = lu_factor(a)
    if singular:
        return lu, piv, np.inf
    return lu, piv, norm_1(a) * inverse_norm_1(lu, piv)


@njit(cache=True)
def det_sign(a: np.ndarray) -> float:
    """Sign of det(a): +1, −1, or 0 when singular."""
    lu, _, swaps, singular = lu_factor(a)
    if singular:
        return 0.0
    sign = -1.0 if swaps % 2 else 1.0
    for i in range(a.shape[0]):
        if lu[i, i] < 0.0:
            sign = -sign
    return sign


@njit(cache=True)
def gram(a: np.ndarray) -> np.ndarray:
    """aᵀ·a, a row at a time over its nonzero entries only (a constraint Jacobian's row has at most six)."""
    m, n = a.shape
    out = np.zeros((n, n))
    cols = np.empty(n, dtype=np.int64)
    for r in range(m):
        k = 0
        for c in range(n):
            if a[r, c] != 0.0:
                cols[k] = c
                k += 1
        for i in range(k):
            ci = cols[i]
            v = a[r, ci]
            for j in range(k):
                out[ci, cols[j]] += v * a[r, cols[j]]
    return out


@njit(cache=True)
def solve_linear(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """x with jac·x = rhs; least squares by the normal equations when jac has more rows than columns.
    NaN where the system is singular."""
    m, n = jac.shape
    if m == n:
        a, b = jac, rhs
    else:
        a, b = gram(jac), jac.T @ rhs
    lu, piv, _, singular = lu_factor(a)
    if singular:
        return np.full(n, np.nan)
    return lu_solve(lu, piv, b)


@njit(cache=True)
def closed_step(jac: np.ndarray, rhs: np.ndarray, drive_rows: np.ndarray, fit_rows: np.ndarray,
                n_hard: int) -> np.ndarray:
    """x with jac·x = rhs for the loop closure: the linkage closed, the measured inputs fitted.

    Square (as many inputs as degrees of freedom): solved. More rows than columns (redundant
    sensors): the hinge rows ``drive_rows[:n_hard]`` hold exactly and the input rows in least
    squares. The k = n − n_hard inputs ``drive_rows[n_hard:]`` close the square system M
    (``drive_rows``); their misfit y is the reduced coordinate: x = M⁻¹(rhs_M + E·y), E the unit
    columns of those rows, the ``fit_rows``' misfit c + B·y with c = J_R·M⁻¹rhs_M − rhs_R and
    B = J_R·M⁻¹E, and y minimises |y|² + |c + B·y|²: (I + BᵀB)·y = −Bᵀc. Without ``drive_rows``
    (no square subsystem closes the pose) every row in least squares (normal equations). NaN where
    singular.
    """
    m, n = jac.shape
    if m == n or drive_rows.shape[0] == 0:
        return solve_linear(jac, rhs)
    a = np.empty((n, n))
    b = np.empty(n)
    for i in range(n):
        a[i] = jac[drive_rows[i]]
        b[i] = rhs[drive_rows[i]]
    lu, piv, _, singular = lu_factor(a)
    if singular:
        return np.full(n, np.nan)
    x = lu_solve(lu, piv, b)
    k = n - n_hard
    g = np.empty((n, k))
    e = np.zeros(n)
    for j in range(k):
        e[n_hard + j] = 1.0
        g[:, j] = lu_solve(lu, piv, e)
        e[n_hard + j] = 0.0
    n_fit = fit_rows.shape[0]
    c = np.empty(n_fit)
    bm = np.empty((n_fit, k))
    for r in range(n_fit):
        row = jac[fit_rows[r]]
        c[r] = row @ x - rhs[fit_rows[r]]
        bm[r] = row @ g
    h = bm.T @ bm
    for j in range(k):
        h[j, j] += 1.0
    lu_h, piv_h, _, singular_h = lu_factor(h)
    if singular_h:
        return np.full(n, np.nan)
    return x + g @ lu_solve(lu_h, piv_h, -(bm.T @ c))


@njit(cache=True)
def _solve_normal(a: np.ndarray) -> bool:
    """Gauss-Jordan in place on a (d, d + 1) = [A | b], A symmetric positive definite (normal
    equations: no pivoting needed): the solution into the last column; False when A is singular."""
    d = a.shape[0]
    for j in range(d):
        pivot = a[j, j]
        if not pivot > 0.0:
            return False
        for c in range(j, d + 1):
            a[j, c] /= pivot
        for i in range(d):
            if i != j:
                f = a[i, j]
                for c in range(j, d + 1):
                    a[i, c] -= f * a[j, c]
    return True


@njit(cache=True)
def _max_abs(v: np.ndarray) -> float:
    """Largest |v_i|; NaN if any entry is NaN."""
    big = 0.0
    for x in v:
        if not abs(x) <= big:
            big = abs(x)
    return big
