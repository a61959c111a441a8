"""Compiled adaptive stiff integrator for the damper model.

Rodas4 (Hairer & Wanner, Solving ODEs II, 1996: the 6-stage, order-4(3),
stiffly accurate Rosenbrock method of their RODAS code, with its dense output)
compiled with numba, on scaled states (bar, mm, cm^3, ...), with a compiled
finite-difference Jacobian, dense output written at the requested sampling
times, and caps on steps (inside) and wall time (between chunks). No Python
runs per time step. ``integrate_batch`` runs many parameter sets in parallel
threads (``prange``) for GA populations.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .model.damper import evaluate
from .model.layout import N_OUT

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

# status codes
OK, MAX_STEPS, STEP_UNDERFLOW, NON_FINITE, WALL_TIME = 0, 1, 2, 3, 4
STATUS_TEXT = {OK: "ok", MAX_STEPS: "step cap reached", STEP_UNDERFLOW: "step size underflow",
               NON_FINITE: "non-finite state", WALL_TIME: "wall-time cap reached"}
# stats slots
ST_STEPS, ST_ACCEPTED, ST_REJECTED, ST_FEVALS, ST_JACS = 0, 1, 2, 3, 4
# controller slots (persist across chunks)
CT_H, CT_HOLD, CT_ERROLD, CT_FIRST, CT_REJECT = 0, 1, 2, 3, 4

SAFE, FAC_MAX, FAC_MIN = 0.9, 5.0, 1.0 / 6.0
H_MIN_REL = 1e-14


@njit(cache=True)
def _f(t, z, sc, p, ex, mc, md, mq, cfg, dz, y, dy, out):
    n = z.shape[0]
    for i in range(n):
        y[i] = z[i] * sc[i]
    evaluate(t, y, p, ex, mc, md, mq, cfg, dy, out)
    for i in range(n):
        dz[i] = dy[i] / sc[i]


@njit(cache=True)
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
        if big == 0.0:
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


@njit(cache=True)
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


@njit(cache=True)
def rodas4(z, t, t_end, t_pause, p, ex, mc, md, mq, cfg, sc, rtol, atol, h_max, t_out, i_out, out_buf,
           channels, ctrl, stats, max_steps, colour, n_colours, col_ptr, row_idx):
    """Integrate scaled state z (in place) from t towards t_end, returning
    after the first accepted step that reaches t_pause (so pausing for a
    wall-time check never changes the step sequence). Writes selected output
    channels at t_out[i_out:] <= t into out_buf. The Jacobian is
    built by forward differences, one RHS evaluation per column colour
    (sparsity.colouring). Returns (status, t, i_out)."""
    n = z.shape[0]
    y = np.empty(n)
    dy = np.empty(n)
    out = np.empty(N_OUT)
    f0 = np.empty(n)
    f1 = np.empty(n)
    ft = np.empty(n)
    jac = np.zeros((n, n))
    dl = np.empty(n)
    zs = np.empty(n)
    a = np.empty((n, n))
    piv = np.empty(n, np.int64)
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
    h = ctrl[CT_H]
    eps = 1.4901161193847656e-08

    _f(t, z, sc, p, ex, mc, md, mq, cfg, f0, y, dy, out)
    stats[ST_FEVALS] += 1
    while t_end - t > H_MIN_REL * max(abs(t), 1.0):
        if stats[ST_STEPS] >= max_steps:
            ctrl[CT_H] = h
            return MAX_STEPS, t, i_out
        # Jacobian by coloured forward differences, and df/dt
        for c in range(n_colours):
            for j in range(n):
                if colour[j] == c:
                    zs[j] = z[j]
                    dl[j] = eps * max(abs(z[j]), 1.0)
                    z[j] += dl[j]
            _f(t, z, sc, p, ex, mc, md, mq, cfg, f1, y, dy, out)
            for j in range(n):
                if colour[j] == c:
                    z[j] = zs[j]
                    for q in range(col_ptr[j], col_ptr[j + 1]):
                        r = row_idx[q]
                        jac[r, j] = (f1[r] - f0[r]) / dl[j]
        dtt = eps * max(abs(t), 1e-3)
        _f(t + dtt, z, sc, p, ex, mc, md, mq, cfg, f1, y, dy, out)
        for i in range(n):
            ft[i] = (f1[i] - f0[i]) / dtt
        stats[ST_FEVALS] += n_colours + 1
        stats[ST_JACS] += 1
        while True:  # attempt steps until one is accepted
            stats[ST_STEPS] += 1
            if stats[ST_STEPS] > max_steps:
                ctrl[CT_H] = h
                return MAX_STEPS, t, i_out
            h = min(h, h_max)
            if t + 1.01 * h >= t_end:  # land on t_end, no sliver step after it
                h = t_end - t
            if h <= H_MIN_REL * max(abs(t), 1.0):
                ctrl[CT_H] = h
                return STEP_UNDERFLOW, t, i_out
            for i in range(n):
                for j in range(n):
                    a[i, j] = -jac[i, j]
                a[i, i] += 1.0 / (_G * h)
            ok = _lu_factor(a, piv)
            finite = ok
            if ok:
                for i in range(n):
                    k1[i] = f0[i] + h * _D1 * ft[i]
                _lu_solve(a, piv, k1)
                for i in range(n):
                    yt[i] = z[i] + _A21 * k1[i]
                _f(t + _C2 * h, yt, sc, p, ex, mc, md, mq, cfg, f1, y, dy, out)
                for i in range(n):
                    k2[i] = f1[i] + h * _D2 * ft[i] + _C21 * k1[i] / h
                _lu_solve(a, piv, k2)
                for i in range(n):
                    yt[i] = z[i] + _A31 * k1[i] + _A32 * k2[i]
                _f(t + _C3 * h, yt, sc, p, ex, mc, md, mq, cfg, f1, y, dy, out)
                for i in range(n):
                    k3[i] = f1[i] + h * _D3 * ft[i] + (_C31 * k1[i] + _C32 * k2[i]) / h
                _lu_solve(a, piv, k3)
                for i in range(n):
                    yt[i] = z[i] + _A41 * k1[i] + _A42 * k2[i] + _A43 * k3[i]
                _f(t + _C4 * h, yt, sc, p, ex, mc, md, mq, cfg, f1, y, dy, out)
                for i in range(n):
                    k4[i] = f1[i] + h * _D4 * ft[i] + (_C41 * k1[i] + _C42 * k2[i] + _C43 * k3[i]) / h
                _lu_solve(a, piv, k4)
                for i in range(n):
                    yt[i] = z[i] + _A51 * k1[i] + _A52 * k2[i] + _A53 * k3[i] + _A54 * k4[i]
                _f(t + h, yt, sc, p, ex, mc, md, mq, cfg, f1, y, dy, out)
                for i in range(n):
                    k5[i] = f1[i] + (_C51 * k1[i] + _C52 * k2[i] + _C53 * k3[i] + _C54 * k4[i]) / h
                _lu_solve(a, piv, k5)
                for i in range(n):
                    yt[i] += k5[i]
                _f(t + h, yt, sc, p, ex, mc, md, mq, cfg, f1, y, dy, out)
                for i in range(n):
                    err_v[i] = f1[i] + (_C61 * k1[i] + _C62 * k2[i] + _C63 * k3[i] + _C64 * k4[i] + _C65 * k5[i]) / h
                _lu_solve(a, piv, err_v)
                stats[ST_FEVALS] += 5
                err = 0.0
                for i in range(n):
                    znew[i] = yt[i] + err_v[i]
                    sk = atol + rtol * max(abs(z[i]), abs(znew[i]))
                    err += (err_v[i] / sk) ** 2
                err = math.sqrt(err / n)
                finite = math.isfinite(err)
            if not finite:
                stats[ST_REJECTED] += 1
                h *= 0.25
                ctrl[CT_REJECT] = 1.0
                continue
            fac = max(FAC_MIN, min(FAC_MAX, err ** 0.25 / SAFE))
            hnew = h / fac
            if err <= 1.0:
                if ctrl[CT_FIRST] == 0.0:
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
            _f(t_out[i_out], zd, sc, p, ex, mc, md, mq, cfg, f1, y, dy, out)
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
                return NON_FINITE, t, i_out
        _f(t, z, sc, p, ex, mc, md, mq, cfg, f0, y, dy, out)
        stats[ST_FEVALS] += 1
        h = hnew
        if t >= t_pause:
            ctrl[CT_H] = h
            return OK, t, i_out
    # flush outputs at t_end that rounding left unwritten
    while i_out < n_out and t_out[i_out] <= t_end * (1.0 + 1e-15):
        _f(t_out[i_out], z, sc, p, ex, mc, md, mq, cfg, f1, y, dy, out)
        for c in range(channels.shape[0]):
            out_buf[i_out, c] = out[channels[c]]
        i_out += 1
    ctrl[CT_H] = h
    return OK, t_end, i_out


@njit(cache=True, parallel=True)
def _batch_chunk(Z, T, t_end, t_pause, P, ex, mc, md, mq, cfg, sc, rtol, atol, h_max, t_out, I_OUT, OUT,
                 channels, CTRL, STATS, STATUS, max_steps, colour, n_colours, col_ptr, row_idx):
    m = Z.shape[0]
    for b in prange(m):
        if STATUS[b] >= 0:
            continue
        st, tb, io = rodas4(Z[b], T[b], t_end, t_pause, P[b], ex, mc, md, mq, cfg, sc, rtol, atol, h_max, t_out,
                            I_OUT[b], OUT[b], channels, CTRL[b], STATS[b], max_steps, colour, n_colours,
                            col_ptr, row_idx)
        T[b] = tb
        I_OUT[b] = io
        if st != OK:
            STATUS[b] = st


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


@functools.lru_cache(maxsize=None)
def _colouring(cfg):
    from .model.sparsity import colouring, pattern

    return colouring(pattern(cfg))


def _ctrl(h0):
    return np.array([h0, h0, 1.0, 1.0, 0.0])


def integrate(p, ex, pq, cfg, y0, t_out, *, rtol=1e-4, atol=None, h0=1e-6, h_max=1e-3,
              max_steps=2_000_000, max_wall_s=None, chunk_s=0.05, channels=None):
    """Integrate one parameter set from t_out[0] over t_out (uniform output
    grid). Returns (outputs[n_t, n_channels], final state, RunStats). A run
    that hits a cap returns what it reached (remaining rows NaN)."""
    from .model.params import state_scales

    sc = state_scales(cfg)
    col = _colouring(cfg)
    z = np.asarray(y0, float) / sc
    atol = rtol if atol is None else atol
    channels = np.arange(N_OUT) if channels is None else np.asarray(channels, np.int64)
    out = np.full((len(t_out), len(channels)), np.nan)
    ctrl = _ctrl(h0)
    stats = np.zeros(5, np.int64)
    mc, md, mq = pq
    t = float(t_out[0])
    i_out = 0
    status = OK
    t0w = time.perf_counter()
    t_final = float(t_out[-1])
    step = chunk_s if max_wall_s is not None else (t_final - t)
    while t < t_final:
        status, t, i_out = rodas4(z, t, t_final, t + step, p, ex, mc, md, mq, cfg, sc, rtol, atol, h_max, t_out,
                                  i_out, out, channels, ctrl, stats, max_steps, *col)
        if status != OK:
            break
        if max_wall_s is not None and time.perf_counter() - t0w > max_wall_s:
            status = WALL_TIME if t < t_final else OK
            break
    wall = time.perf_counter() - t0w
    rs = RunStats(status, STATUS_TEXT[status], int(stats[0]), int(stats[1]), int(stats[2]), int(stats[3]),
                  int(stats[4]), wall)
    return out, z * sc, rs


def integrate_batch(P, ex, pq, cfg, Y0, t_out, *, rtol=1e-4, atol=None, h0=1e-6, h_max=1e-3,
                    max_steps=2_000_000, max_wall_s=None, chunk_s=0.05, channels=None, progress=None):
    """Integrate many parameter sets (rows of P, initial states rows of Y0)
    in parallel threads. Returns (outputs[m, n_t, n_channels], statuses[m],
    stats[m, 5]). Members that fail keep NaN where they did not reach."""
    from .model.params import state_scales

    P = np.ascontiguousarray(P, float)
    m = P.shape[0]
    sc = state_scales(cfg)
    col = _colouring(cfg)
    Z = np.ascontiguousarray(np.asarray(Y0, float) / sc)
    atol = rtol if atol is None else atol
    channels = np.arange(N_OUT) if channels is None else np.asarray(channels, np.int64)
    OUT = np.full((m, len(t_out), len(channels)), np.nan)
    CTRL = np.tile(_ctrl(h0), (m, 1))
    STATS = np.zeros((m, 5), np.int64)
    STATUS = np.full(m, -1, np.int64)
    T = np.full(m, float(t_out[0]))
    I_OUT = np.zeros(m, np.int64)
    mc, md, mq = pq
    t_final = float(t_out[-1])
    t = float(t_out[0])
    t0w = time.perf_counter()
    step = chunk_s if (max_wall_s is not None or progress is not None) else (t_final - t)
    while t < t_final:
        t_pause = t + step
        _batch_chunk(Z, T, t_final, t_pause, P, ex, mc, md, mq, cfg, sc, rtol, atol, h_max, t_out, I_OUT, OUT,
                     channels, CTRL, STATS, STATUS, max_steps, *col)
        t = min(T[STATUS < 0].min(), t_final) if np.any(STATUS < 0) else t_final
        if progress is not None:
            progress(t, t_final)
        if max_wall_s is not None and time.perf_counter() - t0w > max_wall_s and t < t_final:
            STATUS[STATUS < 0] = WALL_TIME
            break
    STATUS[STATUS < 0] = OK
    return OUT, STATUS, STATS
