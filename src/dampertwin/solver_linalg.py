"""The integrator's linear algebra (dampertwin.solver): the dense LU with
partial pivoting, the sparse LU of the iteration matrix along a static fill
plan (reciprocal pivots on its diagonal) and the coloured finite-difference
Jacobian."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

from .jit import lazy_njit
from .solver_base import _A1, _A2, _I1, _JIT, _JIT_NO_NRT, FD_EPS, RHS, _f


@njit(**_JIT_NO_NRT)
def _lu_factor(a, piv):
    n = a.shape[0]
    for k in range(n):
        m = k
        big = abs(a[k, k])
        for i in range(k + 1, n):
            if abs(a[i, k]) > big:
                big = abs(a[i, k])
                m = i
        piv[k] = m
        if big == 0.0 or not math.isfinite(big):
            return False
        if m != k:
            for j in range(n):
                tmp = a[k, j]
                a[k, j] = a[m, j]
                a[m, j] = tmp
        inv = 1.0 / a[k, k]
        for i in range(k + 1, n):
            a[i, k] *= inv
            f = a[i, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= f * a[k, j]
    return True


@njit(**_JIT_NO_NRT)
def _lu_solve(a, piv, b):
    n = a.shape[0]
    for k in range(n):
        m = piv[k]
        if m != k:
            tmp = b[k]
            b[k] = b[m]
            b[m] = tmp
    for i in range(n):
        s = b[i]
        for j in range(i):
            s -= a[i, j] * b[j]
        b[i] = s
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= a[i, j] * b[j]
        b[i] = s / a[i, i]


LU_MAX_MULT = 1e3  # a static-pivot multiplier above this falls back to partial pivoting (threshold pivoting,
#                   Duff, Erisman & Reid, Direct Methods for Sparse Matrices, 1986, sec. 5.4)


def lu_plan(pattern: np.ndarray) -> np.ndarray:
    """Static plan of a sparse LU of the iteration matrix d I - J for a
    Jacobian sparsity ``pattern`` (bool [n, n]): the symbolic fill of Gaussian
    elimination without pivoting in the states' own order, as the index lists
    the compiled factor and solve walk. Packed in one int64 array:
    [n, sparse flag, e_ptr(n+1), u_ptr(n+1), e_rows, u_cols], where
    e_rows[e_ptr[k]:e_ptr[k+1]] are the rows i > k of column k of L and
    u_cols[u_ptr[k]:u_ptr[k+1]] the columns j > k of row k of U.

    The order is fixed (no fill-reducing permutation) so that extra pattern
    entries whose values are exact zeros (a probe that found a spurious
    dependency for one parameter set and not for another) leave every
    floating-point operation on the true non-zeros unchanged: results stay
    bit-identical. A pattern that fills in to more than half the matrix gets
    the flag 0 (dense LU with partial pivoting)."""
    P = np.asarray(pattern, bool)
    n = P.shape[0]
    F = P | np.eye(n, dtype=bool)
    for k in range(n):
        rows, cols = np.flatnonzero(F[k + 1:, k]) + k + 1, np.flatnonzero(F[k, k + 1:]) + k + 1
        F[np.ix_(rows, cols)] = True
    e = [np.flatnonzero(F[k + 1:, k]) + k + 1 for k in range(n)]
    u = [np.flatnonzero(F[k, k + 1:]) + k + 1 for k in range(n)]
    ptr = lambda lists: np.concatenate([[0], np.cumsum([len(x) for x in lists])])  # noqa: E731
    sparse = int(F.sum() <= 0.5 * n * n)
    return np.concatenate([[n, sparse], ptr(e), ptr(u), *e, *u]).astype(np.int64)


@njit(inline="always", **_JIT)
def _it_factor(jac, d, a, piv, plan):
    """Factorise the iteration matrix d I - jac into ``a`` (d = 1/(g h)).
    Sparse static-pivot LU along ``plan`` (:func:`lu_plan`) when it holds
    (pivots non-zero and finite, multipliers <= LU_MAX_MULT), otherwise the
    dense LU with partial pivoting. Returns 1 (sparse: the diagonal of ``a``
    then holds the reciprocal pivots 1/U[k, k]), 2 (dense) or 0 (singular)."""
    n = plan[0]
    if plan[1] == 1:
        ep, up = 2, 3 + n
        er = 4 + 2 * n
        uc = er + plan[ep + n]
        ok = True
        for i in range(n):  # the entries of the fill pattern; fill-ins start at zero
            a[i, i] = d - jac[i, i]
            for q in range(plan[up + i], plan[up + i + 1]):
                j = plan[uc + q]
                a[i, j] = -jac[i, j]
            for q in range(plan[ep + i], plan[ep + i + 1]):
                r = plan[er + q]
                a[r, i] = -jac[r, i]
        for k in range(n):
            pv = a[k, k]
            if pv == 0.0 or not math.isfinite(pv):
                ok = False
                break
            ipv = 1.0 / pv
            a[k, k] = ipv  # the solves multiply by it: no division on their dependency chain
            for q in range(plan[ep + k], plan[ep + k + 1]):
                i = plan[er + q]
                m = a[i, k] * ipv
                if abs(m) > LU_MAX_MULT:
                    ok = False
                    break
                a[i, k] = m
                if m != 0.0:
                    for s in range(plan[up + k], plan[up + k + 1]):
                        j = plan[uc + s]
                        a[i, j] -= m * a[k, j]
            if not ok:
                break
        if ok:
            return 1
    for i in range(n):
        for j in range(n):
            a[i, j] = -jac[i, j]
        a[i, i] += d
    return 2 if _lu_factor(a, piv) else 0


@njit(inline="always", **_JIT)
def _it_solve(a, piv, plan, mode, b):
    """Solve (d I - jac) x = b in place with the factorisation of
    :func:`_it_factor` (``mode`` its return value)."""
    if mode == 2:
        _lu_solve(a, piv, b)
        return
    n = plan[0]
    ep, up = 2, 3 + n
    er = 4 + 2 * n
    uc = er + plan[ep + n]
    for k in range(n):  # L (unit diagonal), column by column
        bk = b[k]
        if bk != 0.0:
            for q in range(plan[ep + k], plan[ep + k + 1]):
                i = plan[er + q]
                b[i] -= a[i, k] * bk
    for i in range(n - 1, -1, -1):  # U, row by row
        s = b[i]
        for q in range(plan[up + i], plan[up + i + 1]):
            j = plan[uc + q]
            s -= a[i, j] * b[j]
        b[i] = s * a[i, i]  # a[i, i] holds 1 / U[i, i]


@njit(**_JIT_NO_NRT)
def _fd_jacobian(rhs, t, z, f0, sc, isc, p, ex, aux, colour, n_colours, col_ptr, row_idx, jac, ft, f1, zs, dl, y, dy,
                 out):
    """Jacobian d(dz)/dz by coloured forward differences (Curtis, Powell &
    Reid 1974: one RHS evaluation per colour of the sparsity pattern) and
    the time derivative ft by one more forward difference."""
    n = z.shape[0]
    for c in range(n_colours):
        for j in range(n):
            if colour[j] == c:
                zs[j] = z[j]
                dl[j] = FD_EPS * max(abs(z[j]), 1.0)
                z[j] += dl[j]
        _f(rhs, t, z, sc, isc, p, ex, aux, f1, y, dy, out)
        for j in range(n):
            if colour[j] == c:
                z[j] = zs[j]
                for q in range(col_ptr[j], col_ptr[j + 1]):
                    r = row_idx[q]
                    jac[r, j] = (f1[r] - f0[r]) / dl[j]
    dtt = FD_EPS * max(abs(t), 1e-3)
    _f(rhs, t + dtt, z, sc, isc, p, ex, aux, f1, y, dy, out)
    for i in range(n):
        ft[i] = (f1[i] - f0[i]) / dtt


@lazy_njit(types.void(RHS, types.float64, _A1, _A1, _A1, _A2, _A1, _I1, types.int64, _I1, _I1, _A2, _A1, types.int64),
      **_JIT)
def fd_jacobian(rhs, t, z, sc, p, ex, aux, colour, n_colours, col_ptr, row_idx, jac, ft, n_rhs_out):
    """Python-callable coloured finite-difference Jacobian of the scaled
    system at (t, z) (for tests and for checking a sparsity pattern)."""
    n = z.shape[0]
    f0 = np.empty(n)
    f1 = np.empty(n)
    zs = np.empty(n)
    dl = np.empty(n)
    y = np.empty(n)
    dy = np.empty(n)
    out = np.empty(n_rhs_out)
    zz = z.copy()
    isc = 1.0 / sc
    _f(rhs, t, zz, sc, isc, p, ex, aux, f0, y, dy, out)
    _fd_jacobian(rhs, t, zz, f0, sc, isc, p, ex, aux, colour, n_colours, col_ptr, row_idx, jac, ft, f1, zs, dl, y, dy,
                 out)

