"""The Rodas4 step loop (dampertwin.solver): Hairer & Wanner, Solving ODEs
II, 1996, the 6-stage, order-4(3), stiffly accurate Rosenbrock method of
their RODAS code with its dense output; a Jacobian every step."""

from __future__ import annotations

import math

from numba import njit

from .jit import lazy_njit
from .solver_base import (CT_ERROLD, CT_FIRST, CT_H, CT_HOLD, CT_REJECT, FAC_MAX, FAC_MIN, H_MIN_REL, MAX_STEPS,
                          NON_FINITE, OK, SAFE, STEP_UNDERFLOW, ST_ACCEPTED, ST_FEVALS, ST_JACS, ST_REJECTED, ST_STEPS,
                          _JIT, _JIT_NO_NRT, _STEP_SIG, _f, work_arrays)
from .solver_linalg import _fd_jacobian, _it_factor, _it_solve

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

_N_WORK = 15  # work rows of the step loop besides 1/sc


@lazy_njit(_STEP_SIG, **_JIT)
def rodas4(rhs, z, t, t_end, t_pause, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out, out_buf,
           channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, n_rhs_out, fixed_h, jac, ft):
    """Integrate scaled state z (in place) from t towards t_end, returning
    after the first accepted step that reaches t_pause (so pausing for a
    wall-time check never changes the step sequence). Writes selected output
    channels at t_out[i_out:] <= t into out_buf. ``fixed_h`` > 0 takes steps
    of exactly that size without error control (for convergence tests).
    Returns (status, t, i_out) as floats."""
    w, a, piv, out = work_arrays(z, sc, _N_WORK, n_rhs_out)
    return _rodas4_loop(rhs, z, t, t_end, t_pause, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out, out_buf,
                        channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, fixed_h, jac,
                        ft, w, a, piv, out)


@njit(**_JIT_NO_NRT)
def _rodas4_loop(rhs, z, t, t_end, t_pause, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out, out_buf,
                 channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx, lu_plan, fixed_h, jac, ft,
                 w, a, piv, out):
    """The step loop of :func:`rodas4` on the work arrays of
    :func:`work_arrays` (it allocates nothing, so it runs without
    reference counting)."""
    n = z.shape[0]
    isc, y, dy, f0, f1, dl, zs, k1, k2, k3, k4, k5, err_v, yt, znew, zd = (w[0], w[1], w[2], w[3], w[4], w[5], w[6],
                                                                          w[7], w[8], w[9], w[10], w[11], w[12],
                                                                          w[13], w[14], w[15])
    mode = 0
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
                err = _rodas4_stages(rhs, t, h, z, f0, ft, sc, isc, p, ex, aux, a, piv, lu_plan, mode, k1, k2, k3, k4,
                                     k5, err_v, yt, znew, f1, y, dy, out, rtol, atol)
                stats[ST_FEVALS] += 5
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
                if ctrl[CT_FIRST] == 0.0:  # Gustafsson's predictive controller (Hairer & Wanner II, IV.8, eq. (8.21))
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


@njit(inline="always", **_JIT)
def _rodas4_stages(rhs, t, h, z, f0, ft, sc, isc, p, ex, aux, a, piv, lu_plan, mode, k1, k2, k3, k4, k5, err_v, yt,
                   znew, f1, y, dy, out, rtol, atol):
    """The six stages of one Rodas4 step from (t, z) with step h [s] on the
    factorisation ``a`` of I/(g h) - J: writes z_new and returns the scaled
    RMS error estimate. Five RHS calls (stage 1 uses f0 = f(t, z))."""
    n = z.shape[0]
    err = 0.0
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
    for i in range(n):
        znew[i] = yt[i] + err_v[i]  # the order-4 solution
        sk = atol + rtol * max(abs(z[i]), abs(znew[i]))
        err += (err_v[i] / sk) ** 2
    return math.sqrt(err / n)
