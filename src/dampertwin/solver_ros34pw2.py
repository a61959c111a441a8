"""The ROS34PW2 step loop (dampertwin.solver): Rang & Angermann 2005, an
order-3(2) Rosenbrock-W method whose Jacobian is kept over steps."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .jit import lazy_njit
from .solver_base import (CT_ERROLD, CT_FIRST, CT_H, CT_HOLD, CT_JAGE, CT_REJECT, FAC_MAX, FAC_MIN, H_KEEP, H_MIN_REL,
                          JAC_MAX_AGE, MAX_STEPS, NON_FINITE, OK, SAFE, STEP_UNDERFLOW, ST_ACCEPTED, ST_FEVALS, ST_JACS,
                          ST_REJECTED, ST_STEPS, _JIT, _JIT_NO_NRT, _STEP_SIG, _f, work_arrays)
from .solver_linalg import _fd_jacobian, _it_factor, _it_solve


# ROS34PW2 (Rang & Angermann, BIT 45 (2005) 761-787): a 4-stage, order-3(2),
# L-stable, stiffly accurate Rosenbrock-W method. Its order holds for any
# approximation of the Jacobian, so the Jacobian is reused across steps.
# Its tables: stage weights alpha (A), the lower-triangular Gamma (diagonal g), weights b, embedded b_hat.
_WG = 0.435866521508459
_W_ALPHA = np.array([[0.0, 0.0, 0.0, 0.0],
                     [0.87173304301691801, 0.0, 0.0, 0.0],
                     [0.84457060015369423, -0.11299064236484185, 0.0, 0.0],
                     [0.0, 0.0, 1.0, 0.0]])
_W_GAMMA = np.array([[_WG, 0.0, 0.0, 0.0],
                     [-0.87173304301691801, _WG, 0.0, 0.0],
                     [-0.90338057013044082, 0.054180672388095326, _WG, 0.0],
                     [0.24212380706095346, -1.2232505839045147, 0.54526025533510214, _WG]])
_W_B = np.array([0.24212380706095346, -1.2232505839045147, 1.5452602553351020, 0.435866521508459])
_W_BHAT = np.array([0.37810903145819369, -0.096042292212423178, 0.5, 0.2179332607542295])
# The step is computed in u_i = sum_j g_ij k_j (Hairer & Wanner, Solving ODEs II, 1996, IV.7,
# "Implementation of Rosenbrock-type methods", as their RODAS code does): with k = Gamma^-1 u the stage
# equations read
#   (I/(g h) - J) u_i = f(t + c_i h, z + sum_j a'_ij u_j) + g_i h f_t + sum_j (c'_ij / h) u_j,
# A' = A Gamma^-1, C' = diag(1/g) - Gamma^-1, error estimate e' = (b - b_hat) Gamma^-1. The same matrix J
# stands on both sides, so this holds for a W-method's kept Jacobian too, and the six J-vector products
# of the k form drop out. The method is stiffly accurate, b = alpha_4 + gamma_4 (row 4 of A and of Gamma),
# so z_new = z + b Gamma^-1 u = Y_4 + u_4; and gamma_4 = sum_j gamma_4j = 0: stage 4 has no f_t term.
_W_GINV = np.linalg.solve(_W_GAMMA, np.eye(4))
_W_AU = _W_ALPHA @ _W_GINV
_W_CU = np.diag(1.0 / np.diag(_W_GAMMA)) - _W_GINV
_W_EU = (_W_B - _W_BHAT) @ _W_GINV
_WU21 = float(_W_AU[1, 0])
_WU31, _WU32 = float(_W_AU[2, 0]), float(_W_AU[2, 1])
_WU41, _WU42, _WU43 = float(_W_AU[3, 0]), float(_W_AU[3, 1]), float(_W_AU[3, 2])
_WC21 = float(_W_CU[1, 0])
_WC31, _WC32 = float(_W_CU[2, 0]), float(_W_CU[2, 1])
_WC41, _WC42, _WC43 = float(_W_CU[3, 0]), float(_W_CU[3, 1]), float(_W_CU[3, 2])
_WE1, _WE2, _WE3, _WE4 = (float(x) for x in _W_EU)
_WC2, _WC3 = float(_W_ALPHA[1].sum()), float(_W_ALPHA[2].sum())  # c_i = sum_j alpha_ij
_WGS2, _WGS3 = float(_W_GAMMA[1].sum()), float(_W_GAMMA[2].sum())  # gamma_i = sum_j gamma_ij (f_t terms)
_N_WORK = 14  # work rows of the step loop besides 1/sc


@lazy_njit(_STEP_SIG, **_JIT)
def ros34pw2(rhs, z, t, t_end, t_pause, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out, out_buf,
             channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, n_rhs_out, fixed_h, jac, ft):
    """Same contract as :func:`rodas4`, with the ROS34PW2 Rosenbrock-W
    method: the Jacobian ``jac`` (and df/dt ``ft``) persist across steps and
    calls and are rebuilt only after a rejected step or JAC_MAX_AGE accepted
    steps. Stage equations (Hairer & Wanner IV.7.4, W form):
    (I - h g J) k_i = h f(t + c_i h, z + sum a_ij k_j) + h J sum g_ij k_j + g_i h^2 f_t,
    solved in u_i = sum_j g_ij k_j (the constants' comment).
    Dense output: cubic Hermite on (z, f) at both ends of the step (order 3)."""
    w, a, piv, out = work_arrays(z, sc, _N_WORK, n_rhs_out)
    return _ros34pw2_loop(rhs, z, t, t_end, t_pause, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out, out_buf,
                          channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, fixed_h, jac,
                          ft, w, a, piv, out)


@njit(**_JIT_NO_NRT)
def _ros34pw2_loop(rhs, z, t, t_end, t_pause, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out, out_buf,
                   channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, fixed_h, jac, ft,
                   w, a, piv, out):
    """The step loop of :func:`ros34pw2` on the work arrays of
    :func:`work_arrays` (it allocates nothing, so it runs without
    reference counting)."""
    n = z.shape[0]
    isc, y, dy, f0, f1, dl, zs, u1, u2, u3, u4, yt, znew, zd, fn = (w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7],
                                                                    w[8], w[9], w[10], w[11], w[12], w[13], w[14])
    mode = 0
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
            fresh = _w_jacobian(rhs, t, z, f0, sc, isc, p, ex, aux, colour, n_colours, col_ptr, row_idx, jac, ft, f1,
                                zs, dl, y, dy, out, stats, ctrl)
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
                err = _w_stages(rhs, t, h, z, f0, ft, sc, isc, p, ex, aux, a, piv, lu_plan, mode, u1, u2, u3, u4, yt,
                                znew, f1, y, dy, out, rtol, atol)
                stats[ST_FEVALS] += 3
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
                    fresh = _w_jacobian(rhs, t, z, f0, sc, isc, p, ex, aux, colour, n_colours, col_ptr, row_idx, jac,
                                        ft, f1, zs, dl, y, dy, out, stats, ctrl)
                    lu_h = -1.0
                continue
            fac = max(FAC_MIN, min(FAC_MAX, err ** (1.0 / 3.0) / SAFE))
            hnew = h / fac
            if ctrl[CT_FIRST] == 0.0:  # Gustafsson's predictive controller (Hairer & Wanner II, IV.8, eq. (8.21))
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
        i_out = _hermite_output(rhs, t, h, z, f0, znew, fn, sc, isc, p, ex, aux, t_out, i_out, out_buf, channels, zd,
                                f1, y, dy, out)
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


@njit(inline="always", **_JIT)
def _w_stages(rhs, t, h, z, f0, ft, sc, isc, p, ex, aux, a, piv, lu_plan, mode, u1, u2, u3, u4, yt, znew, f1, y, dy,
              out, rtol, atol):
    """The four stages of one ROS34PW2 step from (t, z) with step h [s] in
    the variables u_i (the constants' comment), on the factorisation ``a``
    of I/(g h) - J: writes z_new and returns the scaled RMS error estimate.
    Three RHS calls (stage 1 uses f0 = f(t, z))."""
    n = z.shape[0]
    for i in range(n):
        u1[i] = f0[i] + _WG * h * ft[i]
    _it_solve(a, piv, lu_plan, mode, u1)
    for i in range(n):
        yt[i] = z[i] + _WU21 * u1[i]
    _f(rhs, t + _WC2 * h, yt, sc, isc, p, ex, aux, f1, y, dy, out)
    for i in range(n):
        u2[i] = f1[i] + _WGS2 * h * ft[i] + (_WC21 / h) * u1[i]
    _it_solve(a, piv, lu_plan, mode, u2)
    for i in range(n):
        yt[i] = z[i] + _WU31 * u1[i] + _WU32 * u2[i]
    _f(rhs, t + _WC3 * h, yt, sc, isc, p, ex, aux, f1, y, dy, out)
    for i in range(n):
        u3[i] = f1[i] + _WGS3 * h * ft[i] + (_WC31 / h) * u1[i] + (_WC32 / h) * u2[i]
    _it_solve(a, piv, lu_plan, mode, u3)
    for i in range(n):  # Y_4 = z + k_3
        yt[i] = z[i] + _WU41 * u1[i] + _WU42 * u2[i] + _WU43 * u3[i]
    _f(rhs, t + h, yt, sc, isc, p, ex, aux, f1, y, dy, out)
    for i in range(n):  # gamma_4 = 0: no time-derivative term
        u4[i] = f1[i] + (_WC41 / h) * u1[i] + (_WC42 / h) * u2[i] + (_WC43 / h) * u3[i]
    _it_solve(a, piv, lu_plan, mode, u4)
    err = 0.0
    for i in range(n):
        e = _WE1 * u1[i] + _WE2 * u2[i] + _WE3 * u3[i] + _WE4 * u4[i]
        znew[i] = yt[i] + u4[i]  # Y_4 + u_4 (stiffly accurate)
        sk = atol + rtol * max(abs(z[i]), abs(znew[i]))
        err += (e / sk) ** 2
    return math.sqrt(err / n)


@njit(inline="always", **_JIT)
def _w_jacobian(rhs, t, z, f0, sc, isc, p, ex, aux, colour, n_colours, col_ptr, row_idx, jac, ft, f1, zs, dl, y, dy,
                out, stats, ctrl):
    """Rebuild the kept Jacobian and f_t at (t, z) (base point f0 = f(t, z)),
    count it and reset its age. Returns True (the Jacobian is fresh)."""
    _fd_jacobian(rhs, t, z, f0, sc, isc, p, ex, aux, colour, n_colours, col_ptr, row_idx, jac, ft, f1, zs, dl, y, dy,
                 out)
    stats[ST_FEVALS] += n_colours + 1
    stats[ST_JACS] += 1
    ctrl[CT_JAGE] = 0.0
    return True


@njit(inline="always", **_JIT)
def _hermite_output(rhs, t, h, z, f0, znew, fn, sc, isc, p, ex, aux, t_out, i_out, out_buf, channels, zd, f1, y, dy,
                    out):
    """Dense output of the step (t, t + h]: the state by cubic Hermite
    interpolation through (z, f0) and (znew, fn) (order 3), the output
    channels by the RHS at each requested time. Returns the next i_out."""
    n = z.shape[0]
    t_new = t + h
    while i_out < t_out.shape[0] and t_out[i_out] <= t_new * (1.0 + 1e-15):
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
    return i_out
