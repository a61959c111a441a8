"""Compiled adaptive stiff integrator for any compiled right-hand side.

Two Rosenbrock methods compiled with numba: Rodas4 (Hairer & Wanner, Solving
ODEs II, 1996: the 6-stage, order-4(3), stiffly accurate method of their RODAS
code, with its dense output; a Jacobian every step) and ROS34PW2 (Rang &
Angermann 2005: order 3(2), a W-method, so the Jacobian is kept over steps).
Both work on scaled states, with a compiled coloured finite-difference
Jacobian, a sparse LU of the iteration matrix along a static fill plan
(:func:`lu_plan`, partial pivoting as the fallback), dense output written at
the requested sampling times, and caps on steps (inside) and wall time
(between chunks). No Python runs per time step. ``integrate_batch`` runs many parameter sets in parallel
threads (``prange``) for GA populations.

The right-hand side is a first-class compiled function with the signature
``rhs(t, y, p, ex, aux, dy, out)`` (:func:`rhs_signature`): time [s], state
y, parameter vector p, tabulated input ex[2, n], auxiliary data aux (e.g. a
look-up table), the state derivative dy to fill and output channels out to
fill. Compile it with ``@njit(rhs_signature(), cache=True)`` or, to compile
at first use rather than at import, ``@jit.lazy_njit(rhs_signature(),
cache=True)``; this module knows nothing about what it integrates.

The entry points with explicit signatures (the ones Python calls, which
take the right-hand side as a first-class function of type ``RHS``) are
``jit.lazy_njit``: importing this module compiles nothing, each compiles
once at its first use (a cold cache costs about a minute, and a test
collection or a ``--help`` should not pay it).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit, prange, types

from .jit import lazy_njit


def rhs_signature():
    """Numba signature every right-hand side must be compiled with:
    void(t, y, p, ex, aux, dy, out)."""
    a1 = types.float64[::1]
    return types.void(types.float64, a1, a1, types.float64[:, ::1], a1, a1, a1)


RHS = types.FunctionType(rhs_signature())
_A1 = types.float64[::1]
_A2 = types.float64[:, ::1]
_A3 = types.float64[:, :, ::1]
_I1 = types.int64[::1]

# Rodas4 coefficients (Hairer & Wanner, RODAS, METH = 1)
_G = 0.25
_C2, _C3, _C4 = 0.386, 0.21, 0.63
_D1, _D2, _D3, _D4 = 0.25, -0.1043, 0.1035, -0.3620000000000023e-01
_A21 = 1.544
_A31, _A32 = 0.9466785280815826, 0.2557011698983284
_A41, _A42, _A43 = 0.3314825187068521e01, 0.2896124015972201e01, 0.9986419139977817
_A51, _A52, _A53, _A54 = 0.1221224509226641e01, 0.6019134481288629e01, 0.1253708332932087e02, -0.6878860361058950
_C21 = -0.56688e01
_C31, _C32 = -0.2430093356833875e01, -0.2063599157091915
_C41, _C42, _C43 = -0.1073529058151375, -0.9594562251023355e01, -0.2047028614809616e02
_C51, _C52, _C53, _C54 = 0.7496443313967647e01, -0.1024680431464352e02, -0.3399990352819905e02, 0.1170890893206160e02
_C61, _C62, _C63, _C64, _C65 = (0.8083246795921522e01, -0.7981132988064893e01, -0.3152159432874371e02,
                                0.1631930543123136e02, -0.6058818238834054e01)
_E21, _E22, _E23, _E24, _E25 = (0.1012623508344586e02, -0.7487995877610167e01, -0.3480091861555747e02,
                                -0.7992771707568823e01, 0.1025137723295662e01)
_E31, _E32, _E33, _E34, _E35 = (-0.6762803392801253, 0.6087714651680015e01, 0.1643084320892478e02,
                                0.2476722511418386e02, -0.6594389125716872e01)

# ROS34PW2 (Rang & Angermann, BIT 45 (2005) 761-787): a 4-stage, order-3(2),
# L-stable, stiffly accurate Rosenbrock-W method. Its order holds for any
# approximation of the Jacobian, so the Jacobian is reused across steps.
_WG = 0.435866521508459
_WA21 = 0.87173304301691801
_WA31, _WA32 = 0.84457060015369423, -0.11299064236484185
_WG21 = -0.87173304301691801
_WG31, _WG32 = -0.90338057013044082, 0.054180672388095326
_WG41, _WG42, _WG43 = 0.24212380706095346, -1.2232505839045147, 0.54526025533510214
_WB1, _WB2, _WB3, _WB4 = 0.24212380706095346, -1.2232505839045147, 1.5452602553351020, 0.435866521508459
_WE1 = _WB1 - 0.37810903145819369  # b - b_hat (embedded order 2)
_WE2 = _WB2 + 0.096042292212423178
_WE3 = _WB3 - 0.5
_WE4 = _WB4 - 0.2179332607542295
_WC2, _WC3 = _WA21, _WA31 + _WA32
_WGS2, _WGS3 = _WG21 + _WG, _WG31 + _WG32 + _WG  # gamma_i = sum_j gamma_ij (time-derivative terms)
H_KEEP = 1.2  # a step-size increase below this factor is not taken (the LU is reused)
JAC_MAX_AGE = 10  # accepted steps a Jacobian is kept at most (ROS34PW2)

# methods
RODAS4, ROS34PW2 = 0, 1
METHODS = {"rodas4": RODAS4, "ros34pw2": ROS34PW2}

# status codes
OK, MAX_STEPS, STEP_UNDERFLOW, NON_FINITE, WALL_TIME, INVALID, STALLED = 0, 1, 2, 3, 4, 5, 6
STATUS_TEXT = {OK: "ok", MAX_STEPS: "step cap reached", STEP_UNDERFLOW: "step size underflow",
               NON_FINITE: "non-finite state", WALL_TIME: "wall-time cap reached",
               INVALID: "invalid parameters", STALLED: "no progress"}
# stats slots
ST_STEPS, ST_ACCEPTED, ST_REJECTED, ST_FEVALS, ST_JACS = 0, 1, 2, 3, 4
# controller slots (persist across chunks)
CT_H, CT_HOLD, CT_ERROLD, CT_FIRST, CT_REJECT, CT_JAGE = 0, 1, 2, 3, 4, 5

SAFE, FAC_MAX, FAC_MIN = 0.9, 5.0, 1.0 / 6.0
H_MIN_REL = 1e-14
FD_EPS = 1.4901161193847656e-08  # sqrt(machine epsilon): forward-difference increment (relative)

_JIT = dict(cache=True, error_model="numpy")  # 1/0 -> inf -> a NON_FINITE status, never an exception


@njit(inline="always", **_JIT)
def _f(rhs, t, z, sc, isc, p, ex, aux, dz, y, dy, out):
    """Scaled right-hand side: dz = rhs(t, z*sc) / sc, with isc = 1/sc
    (a multiplication: twenty divisions per call cost ~6 % of an RHS call)."""
    n = z.shape[0]
    for i in range(n):
        y[i] = z[i] * sc[i]
    rhs(t, y, p, ex, aux, dy, out)
    for i in range(n):
        dz[i] = dy[i] * isc[i]


@njit(**_JIT)
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


@njit(**_JIT)
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
    dense LU with partial pivoting. Returns 1 (sparse), 2 (dense) or 0 (singular)."""
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
            for q in range(plan[ep + k], plan[ep + k + 1]):
                i = plan[er + q]
                m = a[i, k] / pv
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
        b[i] = s / a[i, i]


@njit(**_JIT)
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


_STEP_SIG = types.UniTuple(types.float64, 3)(
    RHS, _A1, types.float64, types.float64, types.float64, _A1, _A2, _A1, _A1, types.float64, types.float64,
    types.float64, _A1, types.int64, _A2, _I1, _A1, types.int64[::1], types.int64, _I1, types.int64, _I1, _I1,
    _I1, types.int64, types.float64, _A2, _A1)


@lazy_njit(_STEP_SIG, **_JIT)
def rodas4(rhs, z, t, t_end, t_pause, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out, out_buf,
           channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, n_rhs_out, fixed_h, jac, ft):
    """Integrate scaled state z (in place) from t towards t_end, returning
    after the first accepted step that reaches t_pause (so pausing for a
    wall-time check never changes the step sequence). Writes selected output
    channels at t_out[i_out:] <= t into out_buf. ``fixed_h`` > 0 takes steps
    of exactly that size without error control (for convergence tests).
    Returns (status, t, i_out) as floats."""
    n = z.shape[0]
    isc = 1.0 / sc
    y = np.empty(n)
    dy = np.empty(n)
    out = np.empty(n_rhs_out)
    f0 = np.empty(n)
    f1 = np.empty(n)
    dl = np.empty(n)
    zs = np.empty(n)
    a = np.empty((n, n))
    piv = np.empty(n, np.int64)
    mode = 0
    k1 = np.empty(n)
    k2 = np.empty(n)
    k3 = np.empty(n)
    k4 = np.empty(n)
    k5 = np.empty(n)
    err_v = np.empty(n)
    yt = np.empty(n)
    znew = np.empty(n)
    zd = np.empty(n)
    n_out = t_out.shape[0]
    h = fixed_h if fixed_h > 0.0 else ctrl[CT_H]

    _f(rhs, t, z, sc, isc, p, ex, aux, f0, y, dy, out)
    stats[ST_FEVALS] += 1
    while t_end - t > H_MIN_REL * max(abs(t), 1.0):
        if stats[ST_STEPS] >= max_steps:
            ctrl[CT_H] = h
            return float(MAX_STEPS), t, float(i_out)
        _fd_jacobian(rhs, t, z, f0, sc, isc, p, ex, aux, colour, n_colours, col_ptr, row_idx, jac, ft, f1, zs, dl, y,
                     dy, out)
        stats[ST_FEVALS] += n_colours + 1
        stats[ST_JACS] += 1
        while True:  # attempt steps until one is accepted
            stats[ST_STEPS] += 1
            if stats[ST_STEPS] > max_steps:
                ctrl[CT_H] = h
                return float(MAX_STEPS), t, float(i_out)
            if fixed_h > 0.0:
                h = fixed_h
            h = min(h, h_max)
            if t + 1.01 * h >= t_end:  # land on t_end, no sliver step after it
                h = t_end - t
            if not h > H_MIN_REL * max(abs(t), 1.0):
                ctrl[CT_H] = h
                return float(STEP_UNDERFLOW), t, float(i_out)
            mode = _it_factor(jac, 1.0 / (_G * h), a, piv, lu_plan)
            ok = mode > 0
            finite = ok
            err = 0.0
            if ok:
                for i in range(n):
                    k1[i] = f0[i] + h * _D1 * ft[i]
                _it_solve(a, piv, lu_plan, mode, k1)
                for i in range(n):
                    yt[i] = z[i] + _A21 * k1[i]
                _f(rhs, t + _C2 * h, yt, sc, isc, p, ex, aux, f1, y, dy, out)
                for i in range(n):
                    k2[i] = f1[i] + h * _D2 * ft[i] + _C21 * k1[i] / h
                _it_solve(a, piv, lu_plan, mode, k2)
                for i in range(n):
                    yt[i] = z[i] + _A31 * k1[i] + _A32 * k2[i]
                _f(rhs, t + _C3 * h, yt, sc, isc, p, ex, aux, f1, y, dy, out)
                for i in range(n):
                    k3[i] = f1[i] + h * _D3 * ft[i] + (_C31 * k1[i] + _C32 * k2[i]) / h
                _it_solve(a, piv, lu_plan, mode, k3)
                for i in range(n):
                    yt[i] = z[i] + _A41 * k1[i] + _A42 * k2[i] + _A43 * k3[i]
                _f(rhs, t + _C4 * h, yt, sc, isc, p, ex, aux, f1, y, dy, out)
                for i in range(n):
                    k4[i] = f1[i] + h * _D4 * ft[i] + (_C41 * k1[i] + _C42 * k2[i] + _C43 * k3[i]) / h
                _it_solve(a, piv, lu_plan, mode, k4)
                for i in range(n):
                    yt[i] = z[i] + _A51 * k1[i] + _A52 * k2[i] + _A53 * k3[i] + _A54 * k4[i]
                _f(rhs, t + h, yt, sc, isc, p, ex, aux, f1, y, dy, out)
                for i in range(n):
                    k5[i] = f1[i] + (_C51 * k1[i] + _C52 * k2[i] + _C53 * k3[i] + _C54 * k4[i]) / h
                _it_solve(a, piv, lu_plan, mode, k5)
                for i in range(n):
                    yt[i] += k5[i]  # the embedded order-3 solution
                _f(rhs, t + h, yt, sc, isc, p, ex, aux, f1, y, dy, out)
                for i in range(n):
                    err_v[i] = f1[i] + (_C61 * k1[i] + _C62 * k2[i] + _C63 * k3[i] + _C64 * k4[i] + _C65 * k5[i]) / h
                _it_solve(a, piv, lu_plan, mode, err_v)
                stats[ST_FEVALS] += 5
                for i in range(n):
                    znew[i] = yt[i] + err_v[i]  # the order-4 solution
                    sk = atol + rtol * max(abs(z[i]), abs(znew[i]))
                    err += (err_v[i] / sk) ** 2
                err = math.sqrt(err / n)
                finite = math.isfinite(err)
            if fixed_h > 0.0:
                if not finite:
                    ctrl[CT_H] = h
                    return float(NON_FINITE), t, float(i_out)
                hnew = h
                break
            if not finite:
                stats[ST_REJECTED] += 1
                h *= 0.25
                ctrl[CT_REJECT] = 1.0
                continue
            fac = max(FAC_MIN, min(FAC_MAX, err ** 0.25 / SAFE))
            hnew = h / fac
            if err <= 1.0:
                if ctrl[CT_FIRST] == 0.0:  # Gustafsson's predictive controller
                    facpred = (ctrl[CT_HOLD] / h) * (err * err / ctrl[CT_ERROLD]) ** 0.25 / SAFE
                    facpred = max(FAC_MIN, min(FAC_MAX, facpred))
                    fac = max(fac, facpred)
                    hnew = h / fac
                ctrl[CT_FIRST] = 0.0
                ctrl[CT_HOLD] = h
                ctrl[CT_ERROLD] = max(0.01, err)
                if ctrl[CT_REJECT] > 0.0:
                    hnew = min(hnew, h)
                ctrl[CT_REJECT] = 0.0
                break
            stats[ST_REJECTED] += 1
            ctrl[CT_REJECT] = 1.0
            h = hnew
        # accepted: dense output at the requested times in (t, t + h]
        t_new = t + h
        while i_out < n_out and t_out[i_out] <= t_new * (1.0 + 1e-15):
            s = (t_out[i_out] - t) / h
            s1 = 1.0 - s
            for i in range(n):
                c3 = _E21 * k1[i] + _E22 * k2[i] + _E23 * k3[i] + _E24 * k4[i] + _E25 * k5[i]
                c4 = _E31 * k1[i] + _E32 * k2[i] + _E33 * k3[i] + _E34 * k4[i] + _E35 * k5[i]
                zd[i] = z[i] * s1 + s * (znew[i] + s1 * (c3 + s * c4))
            _f(rhs, t_out[i_out], zd, sc, isc, p, ex, aux, f1, y, dy, out)
            for c in range(channels.shape[0]):
                out_buf[i_out, c] = out[channels[c]]
            i_out += 1
        for i in range(n):
            z[i] = znew[i]
        t = t_new
        stats[ST_ACCEPTED] += 1
        for i in range(n):
            if not math.isfinite(z[i]):
                ctrl[CT_H] = h
                return float(NON_FINITE), t, float(i_out)
        _f(rhs, t, z, sc, isc, p, ex, aux, f0, y, dy, out)
        stats[ST_FEVALS] += 1
        h = hnew
        if t >= t_pause:
            ctrl[CT_H] = h
            return float(OK), t, float(i_out)
    # flush outputs at t_end that rounding left unwritten
    while i_out < n_out and t_out[i_out] <= t_end * (1.0 + 1e-15):
        _f(rhs, t_out[i_out], z, sc, isc, p, ex, aux, f1, y, dy, out)
        for c in range(channels.shape[0]):
            out_buf[i_out, c] = out[channels[c]]
        i_out += 1
    ctrl[CT_H] = h
    return float(OK), t_end, float(i_out)


@njit(**_JIT)
def _jac_mul_add(jac, col_ptr, row_idx, v, c, acc):
    """acc += c * J v over the sparsity pattern (CSC)."""
    for j in range(v.shape[0]):
        vj = c * v[j]
        if vj != 0.0:
            for q in range(col_ptr[j], col_ptr[j + 1]):
                r = row_idx[q]
                acc[r] += jac[r, j] * vj


@lazy_njit(_STEP_SIG, **_JIT)
def ros34pw2(rhs, z, t, t_end, t_pause, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out, out_buf,
             channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, n_rhs_out, fixed_h, jac, ft):
    """Same contract as :func:`rodas4`, with the ROS34PW2 Rosenbrock-W
    method: the Jacobian ``jac`` (and df/dt ``ft``) persist across steps and
    calls and are rebuilt only after a rejected step or JAC_MAX_AGE accepted
    steps. Stage equations (Hairer & Wanner IV.7.4, W form):
    (I - h g J) k_i = h f(t + c_i h, z + sum a_ij k_j) + h J sum g_ij k_j + g_i h^2 f_t.
    Dense output: cubic Hermite on (z, f) at both ends of the step (order 3)."""
    n = z.shape[0]
    isc = 1.0 / sc
    y = np.empty(n)
    dy = np.empty(n)
    out = np.empty(n_rhs_out)
    f0 = np.empty(n)
    f1 = np.empty(n)
    dl = np.empty(n)
    zs = np.empty(n)
    a = np.empty((n, n))
    piv = np.empty(n, np.int64)
    mode = 0
    k1 = np.empty(n)
    k2 = np.empty(n)
    k3 = np.empty(n)
    k4 = np.empty(n)
    yt = np.empty(n)
    znew = np.empty(n)
    zd = np.empty(n)
    fn = np.empty(n)
    n_out = t_out.shape[0]
    h = fixed_h if fixed_h > 0.0 else ctrl[CT_H]
    lu_h = -1.0  # step size of the factorisation held in a (-1: none); reset when J changes

    _f(rhs, t, z, sc, isc, p, ex, aux, f0, y, dy, out)
    stats[ST_FEVALS] += 1
    while t_end - t > H_MIN_REL * max(abs(t), 1.0):
        if stats[ST_STEPS] >= max_steps:
            ctrl[CT_H] = h
            return float(MAX_STEPS), t, float(i_out)
        fresh = False
        if ctrl[CT_JAGE] >= JAC_MAX_AGE:
            _fd_jacobian(rhs, t, z, f0, sc, isc, p, ex, aux, colour, n_colours, col_ptr, row_idx, jac, ft, f1, zs, dl,
                         y, dy, out)
            stats[ST_FEVALS] += n_colours + 1
            stats[ST_JACS] += 1
            ctrl[CT_JAGE] = 0.0
            fresh = True
            lu_h = -1.0
        while True:  # attempt steps until one is accepted
            stats[ST_STEPS] += 1
            if stats[ST_STEPS] > max_steps:
                ctrl[CT_H] = h
                return float(MAX_STEPS), t, float(i_out)
            if fixed_h > 0.0:
                h = fixed_h
            h = min(h, h_max)
            if t + 1.01 * h >= t_end:
                h = t_end - t
            if not h > H_MIN_REL * max(abs(t), 1.0):
                ctrl[CT_H] = h
                return float(STEP_UNDERFLOW), t, float(i_out)
            if h != lu_h:  # same J and h: the factorisation of I/(g h) - J is unchanged
                mode = _it_factor(jac, 1.0 / (_WG * h), a, piv, lu_plan)
                lu_ok = mode > 0
                lu_h = h if lu_ok else -1.0
            else:
                lu_ok = True
            ok = lu_ok
            finite = ok
            err = 0.0
            if ok:
                # stage 1
                for i in range(n):
                    k1[i] = (f0[i] + _WG * h * ft[i]) / _WG  # divided by g: a holds (I/(g h) - J)
                _it_solve(a, piv, lu_plan, mode, k1)
                # stage 2
                for i in range(n):
                    yt[i] = z[i] + _WA21 * k1[i]
                _f(rhs, t + _WC2 * h, yt, sc, isc, p, ex, aux, f1, y, dy, out)
                for i in range(n):
                    k2[i] = f1[i] + _WGS2 * h * ft[i]
                _jac_mul_add(jac, col_ptr, row_idx, k1, _WG21, k2)
                for i in range(n):
                    k2[i] /= _WG
                _it_solve(a, piv, lu_plan, mode, k2)
                # stage 3
                for i in range(n):
                    yt[i] = z[i] + _WA31 * k1[i] + _WA32 * k2[i]
                _f(rhs, t + _WC3 * h, yt, sc, isc, p, ex, aux, f1, y, dy, out)
                for i in range(n):
                    k3[i] = f1[i] + _WGS3 * h * ft[i]
                _jac_mul_add(jac, col_ptr, row_idx, k1, _WG31, k3)
                _jac_mul_add(jac, col_ptr, row_idx, k2, _WG32, k3)
                for i in range(n):
                    k3[i] /= _WG
                _it_solve(a, piv, lu_plan, mode, k3)
                # stage 4 (z + k3: the stiffly accurate end point)
                for i in range(n):
                    yt[i] = z[i] + k3[i]
                _f(rhs, t + h, yt, sc, isc, p, ex, aux, f1, y, dy, out)
                for i in range(n):
                    k4[i] = f1[i]
                _jac_mul_add(jac, col_ptr, row_idx, k1, _WG41, k4)
                _jac_mul_add(jac, col_ptr, row_idx, k2, _WG42, k4)
                _jac_mul_add(jac, col_ptr, row_idx, k3, _WG43, k4)
                for i in range(n):
                    k4[i] /= _WG
                _it_solve(a, piv, lu_plan, mode, k4)
                stats[ST_FEVALS] += 3
                for i in range(n):
                    e = _WE1 * k1[i] + _WE2 * k2[i] + _WE3 * k3[i] + _WE4 * k4[i]
                    znew[i] = z[i] + _WB1 * k1[i] + _WB2 * k2[i] + _WB3 * k3[i] + _WB4 * k4[i]
                    sk = atol + rtol * max(abs(z[i]), abs(znew[i]))
                    err += (e / sk) ** 2
                err = math.sqrt(err / n)
                finite = math.isfinite(err)
            if fixed_h > 0.0:
                if not finite:
                    ctrl[CT_H] = h
                    return float(NON_FINITE), t, float(i_out)
                hnew = h
                break
            if not finite or err > 1.0:
                stats[ST_REJECTED] += 1
                ctrl[CT_REJECT] = 1.0
                if finite:
                    h = h / max(FAC_MIN, min(FAC_MAX, err ** (1.0 / 3.0) / SAFE))
                else:
                    h *= 0.25
                if not fresh:  # a stale Jacobian may be the culprit: rebuild it once
                    _fd_jacobian(rhs, t, z, f0, sc, isc, p, ex, aux, colour, n_colours, col_ptr, row_idx, jac, ft, f1,
                                 zs, dl, y, dy, out)
                    stats[ST_FEVALS] += n_colours + 1
                    stats[ST_JACS] += 1
                    ctrl[CT_JAGE] = 0.0
                    fresh = True
                    lu_h = -1.0
                continue
            fac = max(FAC_MIN, min(FAC_MAX, err ** (1.0 / 3.0) / SAFE))
            hnew = h / fac
            if ctrl[CT_FIRST] == 0.0:  # Gustafsson's predictive controller
                facpred = (ctrl[CT_HOLD] / h) * (err * err / ctrl[CT_ERROLD]) ** (1.0 / 3.0) / SAFE
                facpred = max(FAC_MIN, min(FAC_MAX, facpred))
                fac = max(fac, facpred)
                hnew = h / fac
            ctrl[CT_FIRST] = 0.0
            ctrl[CT_HOLD] = h
            ctrl[CT_ERROLD] = max(0.01, err)
            if ctrl[CT_REJECT] > 0.0:
                hnew = min(hnew, h)
            if h <= hnew <= H_KEEP * h:  # keep h (and so the factorisation) for a small increase
                hnew = h
            ctrl[CT_REJECT] = 0.0
            break
        t_new = t + h
        for i in range(n):
            if not math.isfinite(znew[i]):
                ctrl[CT_H] = h
                return float(NON_FINITE), t, float(i_out)
        _f(rhs, t_new, znew, sc, isc, p, ex, aux, fn, y, dy, out)
        stats[ST_FEVALS] += 1
        # dense output: cubic Hermite through (z, f0) and (znew, fn)
        while i_out < n_out and t_out[i_out] <= t_new * (1.0 + 1e-15):
            s = (t_out[i_out] - t) / h
            s2 = s * s
            s3 = s2 * s
            h00 = 2 * s3 - 3 * s2 + 1
            h10 = s3 - 2 * s2 + s
            h01 = -2 * s3 + 3 * s2
            h11 = s3 - s2
            for i in range(n):
                zd[i] = h00 * z[i] + h10 * h * f0[i] + h01 * znew[i] + h11 * h * fn[i]
            _f(rhs, t_out[i_out], zd, sc, isc, p, ex, aux, f1, y, dy, out)
            for c in range(channels.shape[0]):
                out_buf[i_out, c] = out[channels[c]]
            i_out += 1
        for i in range(n):
            z[i] = znew[i]
            f0[i] = fn[i]
        t = t_new
        stats[ST_ACCEPTED] += 1
        ctrl[CT_JAGE] += 1.0
        fresh = False
        h = hnew
        if t >= t_pause:
            ctrl[CT_H] = h
            return float(OK), t, float(i_out)
    while i_out < n_out and t_out[i_out] <= t_end * (1.0 + 1e-15):
        _f(rhs, t_out[i_out], z, sc, isc, p, ex, aux, f1, y, dy, out)
        for c in range(channels.shape[0]):
            out_buf[i_out, c] = out[channels[c]]
        i_out += 1
    ctrl[CT_H] = h
    return float(OK), t_end, float(i_out)


@lazy_njit(_STEP_SIG.return_type(types.int64, *_STEP_SIG.args), **_JIT)
def step_chunk(method, rhs, z, t, t_end, t_pause, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out, out_buf,
               channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, n_rhs_out, fixed_h, jac, ft):
    """Dispatch to the integration method (RODAS4 | ROS34PW2)."""
    if method == ROS34PW2:
        return ros34pw2(rhs, z, t, t_end, t_pause, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out, out_buf,
                        channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, n_rhs_out, fixed_h,
                        jac, ft)
    return rodas4(rhs, z, t, t_end, t_pause, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out, out_buf,
                  channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, n_rhs_out, fixed_h, jac, ft)


@lazy_njit(types.void(types.int64, RHS, _A2, _A1, types.float64, types.float64, _A2, _A2, _A1, _A1, types.float64,
                 types.float64, types.float64, _A1, types.int64[::1], _A3, _I1, _A2, types.int64[:, ::1],
                 types.int64[::1], types.int64, _I1, types.int64, _I1, _I1, _I1, types.int64, _A3, _A2),
      parallel=True, **_JIT)
def _batch_chunk(method, rhs, Z, T, t_end, t_pause, P, ex, aux, sc, rtol, atol, h_max, t_out, I_OUT, OUT,
                 channels, CTRL, STATS, STATUS, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, n_rhs_out, JAC, FT):
    m = Z.shape[0]
    for b in prange(m):
        if STATUS[b] >= 0:
            continue
        st, tb, io = step_chunk(method, rhs, Z[b], T[b], t_end, t_pause, P[b], ex, aux, sc, rtol, atol, h_max,
                                t_out, I_OUT[b], OUT[b], channels, CTRL[b], STATS[b], max_steps, colour, n_colours,
                                col_ptr, row_idx, lu_plan, n_rhs_out, 0.0, JAC[b], FT[b])
        T[b] = tb
        I_OUT[b] = int(io)
        if int(st) != OK:
            STATUS[b] = int(st)


@dataclass
class RunStats:
    status: int
    message: str
    steps: int
    accepted: int
    rejected: int
    fevals: int
    jacobians: int
    wall_s: float

    @property
    def ok(self) -> bool:
        return self.status == OK

    @property
    def rejection_rate(self) -> float:
        return self.rejected / self.steps if self.steps else 0.0

    @property
    def fevals_per_step(self) -> float:
        return self.fevals / self.accepted if self.accepted else float("nan")


@dataclass(frozen=True)
class Sparsity:
    """A Jacobian sparsity pattern and its column colouring (Curtis-Powell-Reid)."""

    pattern: np.ndarray  # bool [n, n]: may d(dy_i)/d(y_j) be non-zero
    colour: np.ndarray  # colour of each column
    n_colours: int
    col_ptr: np.ndarray  # CSC structure of the pattern
    row_idx: np.ndarray
    lu_plan: np.ndarray  # sparse LU of the iteration matrix (:func:`lu_plan`)

    @classmethod
    def from_pattern(cls, J: np.ndarray) -> "Sparsity":
        J = np.asarray(J, bool)
        colour, nc = colouring(J)
        col_ptr = np.zeros(J.shape[1] + 1, np.int64)
        rows: list[int] = []
        for j in range(J.shape[1]):
            r = np.flatnonzero(J[:, j])
            rows.extend(r)
            col_ptr[j + 1] = col_ptr[j] + len(r)
        return cls(J, colour, nc, col_ptr, np.asarray(rows, np.int64), lu_plan(J))

    @classmethod
    def dense(cls, n: int) -> "Sparsity":
        return cls.from_pattern(np.ones((n, n), bool))

    def args(self):
        return self.colour, self.n_colours, self.col_ptr, self.row_idx


def colouring(J: np.ndarray) -> tuple[np.ndarray, int]:
    """Greedy column colouring, largest columns first: columns of one colour
    share no row. Returns (colour per column, number of colours)."""
    n = J.shape[1]
    colour = -np.ones(n, np.int64)
    order = np.argsort(-J.sum(axis=0), kind="stable")
    for j in order:
        used = {colour[k] for k in range(n) if colour[k] >= 0 and np.any(J[:, k] & J[:, j])}
        c = 0
        while c in used:
            c += 1
        colour[j] = c
    return colour, int(colour.max()) + 1


@lazy_njit(types.void(RHS, _A2, _A1, _A1, _A2, _A2, _A1, types.int64, types.boolean[:, ::1]), **_JIT)
def _probe(rhs, Y, sc, tt, P, ex, aux, n_rhs_out, J):
    n = Y.shape[1]
    f0 = np.empty(n)
    f1 = np.empty(n)
    out = np.empty(n_rhs_out)
    y = np.empty(n)
    for k in range(Y.shape[0]):
        p = P[k % P.shape[0]]
        for i in range(n):
            y[i] = Y[k, i]
        rhs(tt[k], y, p, ex, aux, f0, out)
        for j in range(n):
            yj = y[j]
            for rel in (1e-7, -1e-4):
                y[j] = yj + rel * max(abs(yj), sc[j])
                rhs(tt[k], y, p, ex, aux, f1, out)
                for i in range(n):
                    if f1[i] != f0[i] and not (math.isnan(f1[i]) and math.isnan(f0[i])):
                        J[i, j] = True
            y[j] = yj


def probe_sparsity(rhs, Y: np.ndarray, scales: np.ndarray, times: np.ndarray, P: np.ndarray, ex: np.ndarray,
                   aux: np.ndarray, n_rhs_out: int) -> np.ndarray:
    """Sparsity pattern found by perturbing every state of the compiled RHS
    (by 1e-7 and -1e-4 of max(|y_j|, scale_j)) at the sample states Y[k]
    (times[k], parameters P[k mod len(P)]): entry (i, j) is set when dy_i
    changed. The diagonal is always included."""
    Y = np.ascontiguousarray(Y, float)
    J = np.zeros((Y.shape[1], Y.shape[1]), bool)
    _probe(rhs, Y, np.ascontiguousarray(scales, float), np.ascontiguousarray(times, float), np.ascontiguousarray(np.atleast_2d(P), float),
           np.ascontiguousarray(ex, float), np.ascontiguousarray(aux, float), int(n_rhs_out), J)
    J |= np.eye(len(J), dtype=bool)
    return J


def _method(method: str) -> int:
    if method not in METHODS:
        raise ValueError(f"method must be one of {list(METHODS)}, got {method!r}")
    return METHODS[method]


def _ctrl(h0):
    return np.array([h0, h0, 1.0, 1.0, 0.0, 1e9])


def _prepare(sc, sparsity, n, atol, rtol, channels, n_rhs_out):
    sc = np.ascontiguousarray(sc, float)
    if sc.shape != (n,):
        raise ValueError(f"scales must have one entry per state ({n}), got shape {sc.shape}")
    sp = Sparsity.dense(n) if sparsity is None else sparsity
    atol = rtol if atol is None else atol
    channels = np.arange(n_rhs_out) if channels is None else np.asarray(channels, np.int64)
    return sc, sp, float(atol), np.ascontiguousarray(channels, np.int64)


def integrate(rhs, p, ex, aux, y0, t_out, *, scales=None, n_rhs_out=1, sparsity=None, rtol=1e-4, atol=None,
              h0=1e-6, h_max=1e-3, max_steps=2_000_000, max_wall_s=None, chunk_s=0.05, channels=None,
              fixed_h=0.0, method="rodas4"):
    """Integrate ``rhs`` (compiled with :func:`rhs_signature`) for parameters
    p from y0 at t_out[0] over the output grid t_out. ``scales`` (typical
    state magnitudes; default 1) define the error norm; ``sparsity`` (a
    :class:`Sparsity`; default dense) the finite-difference Jacobian;
    ``n_rhs_out`` the length of the RHS's ``out`` vector; ``method`` "rodas4"
    (order 4, Jacobian every step) or "ros34pw2" (order 3 W-method,
    Jacobian reused). Returns (outputs[n_t,
    n_channels], final state, RunStats); a run that hits a cap returns what it
    reached (remaining rows NaN)."""
    y0 = np.asarray(y0, float)
    n = len(y0)
    sc, sp, atol, channels = _prepare(np.ones(n) if scales is None else scales, sparsity, n, atol, rtol, channels,
                                      n_rhs_out)
    z = np.ascontiguousarray(y0 / sc)
    t_out = np.ascontiguousarray(t_out, float)
    out = np.full((len(t_out), len(channels)), np.nan)
    ctrl = _ctrl(h0)
    stats = np.zeros(5, np.int64)
    p = np.ascontiguousarray(p, float)
    ex = np.ascontiguousarray(ex, float)
    aux = np.ascontiguousarray(aux, float)
    t = float(t_out[0])
    i_out = 0
    status = OK
    t0w = time.perf_counter()
    t_final = float(t_out[-1])
    step = chunk_s if max_wall_s is not None else (t_final - t)
    meth = _method(method)
    jac, ft = np.zeros((n, n)), np.zeros(n)
    while t < t_final:
        st, t, io = step_chunk(meth, rhs, z, t, t_final, t + step, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out,
                               out, channels, ctrl, stats, max_steps, *sp.args(), sp.lu_plan, n_rhs_out, float(fixed_h),
                               jac, ft)
        status, i_out = int(st), int(io)
        if status != OK:
            break
        if max_wall_s is not None and time.perf_counter() - t0w > max_wall_s:
            status = WALL_TIME if t < t_final else OK
            break
    wall = time.perf_counter() - t0w
    rs = RunStats(status, STATUS_TEXT[status], int(stats[0]), int(stats[1]), int(stats[2]), int(stats[3]),
                  int(stats[4]), wall)
    return out, z * sc, rs


def integrate_batch(rhs, P, ex, aux, Y0, t_out, *, scales=None, n_rhs_out=1, sparsity=None, rtol=1e-4,
                    atol=None, h0=1e-6, h_max=1e-3, max_steps=2_000_000, max_wall_s=None, chunk_s=0.05,
                    channels=None, progress=None, skip=None, method="rodas4"):
    """Integrate many parameter sets (rows of P, initial states rows of Y0)
    in parallel threads. ``skip`` (bool per member) marks members not to run
    (status INVALID). Returns (outputs[m, n_t, n_channels], statuses[m],
    stats[m, 5]). Members that fail keep NaN where they did not reach; the
    others are unaffected."""
    P = np.ascontiguousarray(P, float)
    m = P.shape[0]
    Y0 = np.asarray(Y0, float)
    n = Y0.shape[1]
    sc, sp, atol, channels = _prepare(np.ones(n) if scales is None else scales, sparsity, n, atol, rtol, channels,
                                      n_rhs_out)
    Z = np.ascontiguousarray(Y0 / sc)
    t_out = np.ascontiguousarray(t_out, float)
    OUT = np.full((m, len(t_out), len(channels)), np.nan)
    CTRL = np.tile(_ctrl(h0), (m, 1))
    STATS = np.zeros((m, 5), np.int64)
    STATUS = np.full(m, -1, np.int64)
    if skip is not None:
        STATUS[np.asarray(skip, bool)] = INVALID
    T = np.full(m, float(t_out[0]))
    I_OUT = np.zeros(m, np.int64)
    meth = _method(method)
    JAC, FT = np.zeros((m, n, n)), np.zeros((m, n))
    ex = np.ascontiguousarray(ex, float)
    aux = np.ascontiguousarray(aux, float)
    t_final = float(t_out[-1])
    t = float(t_out[0])
    t0w = time.perf_counter()
    step = chunk_s if (max_wall_s is not None or progress is not None) else (t_final - t)
    while np.any(STATUS < 0):
        t_pause = t + step
        T_before = T.copy()
        _batch_chunk(meth, rhs, Z, T, t_final, t_pause, P, ex, aux, sc, rtol, atol, h_max, t_out, I_OUT, OUT,
                     channels, CTRL, STATS, STATUS, max_steps, *sp.args(), sp.lu_plan, n_rhs_out, JAC, FT)
        running = STATUS < 0
        done = running & (T >= t_final)
        STATUS[done] = OK
        stalled = (STATUS < 0) & ~(T > T_before)  # a member whose time did not advance: never loop on it
        STATUS[stalled] = STALLED
        if not np.any(STATUS < 0):
            break
        t = min(float(T[STATUS < 0].min()), t_final)
        if progress is not None:
            progress(t, t_final)
        if max_wall_s is not None and time.perf_counter() - t0w > max_wall_s:
            STATUS[STATUS < 0] = WALL_TIME
            break
    if progress is not None:
        progress(t_final, t_final)
    return OUT, STATUS, STATS
