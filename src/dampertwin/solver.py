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

Its parts: solver_base (signature, codes, controller constants, the scaled
right-hand side, the step loops' work arrays), solver_linalg (LU, finite-difference Jacobian),
solver_rodas4 and solver_ros34pw2 (the step loops); this module dispatches
and drives them from Python (numba_cache.cache_sources hashes every solver_*.py
into numba's cache folder).
"""

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import prange, types

from .jit import lazy_njit
from .solver_base import (_A1, _A2, _A3, _I1, _JIT, _STEP_SIG, FD_EPS, H_KEEP, H_MIN_REL, INVALID, JAC_MAX_AGE, MAX_STEPS,
                          METHODS, NON_FINITE, OK, RHS, RODAS4, ROS34PW2, STALLED, STATUS_TEXT, STEP_UNDERFLOW,
                          WALL_TIME, rhs_signature)
from .solver_linalg import LU_MAX_MULT, _it_factor, _it_solve, fd_jacobian, lu_plan
from .solver_rodas4 import rodas4
from .solver_ros34pw2 import ros34pw2


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


def _compile(*kernels) -> None:
    """Compile (or load from numba's cache) the lazy kernels a run calls
    before its wall clock starts: ``max_wall_s`` caps the integration, not
    the compilation (a cold cache on a loaded machine once took longer than
    a caller's cap, and the run ended as WALL_TIME before its first step)."""
    for k in kernels:
        getattr(k, "dispatcher", None)


_CALLED: set = set()  # (kernel name, right-hand side) pairs this process has run at least once


def _first_call(kernel: str, rhs) -> bool:
    """True the first time this process runs ``kernel`` with this right-hand
    side: numba then builds, inside that first call, what the kernel needs
    to call the RHS as a first-class function (its wrapper), which
    :func:`_compile` cannot reach; the caller restarts its wall clock after
    that call, so ``max_wall_s`` does not count it (nor, once per RHS and
    process, the first chunk's integration)."""
    key = (kernel, rhs)
    if key in _CALLED:
        return False
    _CALLED.add(key)
    return True


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
    _compile(step_chunk, rhs)
    first = _first_call("step_chunk", rhs)
    t0w = time.perf_counter()
    t_final = float(t_out[-1])
    step = chunk_s if max_wall_s is not None else (t_final - t)
    meth = _method(method)
    jac, ft = np.zeros((n, n)), np.zeros(n)
    while t < t_final:
        st, t, io = step_chunk(meth, rhs, z, t, t_final, t + step, p, ex, aux, sc, rtol, atol, h_max, t_out, i_out,
                               out, channels, ctrl, stats, max_steps, *sp.args(), sp.lu_plan, n_rhs_out, float(fixed_h),
                               jac, ft)
        if first:  # the RHS's first-class wrapper was built in that call: not the integration's time
            first, t0w = False, time.perf_counter()
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
    _compile(_batch_chunk, step_chunk, rhs)
    first = _first_call("_batch_chunk", rhs)
    t0w = time.perf_counter()
    step = chunk_s if (max_wall_s is not None or progress is not None) else (t_final - t)
    while np.any(STATUS < 0):
        t_pause = t + step
        T_before = T.copy()
        _batch_chunk(meth, rhs, Z, T, t_final, t_pause, P, ex, aux, sc, rtol, atol, h_max, t_out, I_OUT, OUT,
                     channels, CTRL, STATS, STATUS, max_steps, *sp.args(), sp.lu_plan, n_rhs_out, JAC, FT)
        if first:  # as in integrate: the first call with this RHS built its wrapper
            first, t0w = False, time.perf_counter()
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


# the integrator's API (its parts live in solver_base, solver_linalg, solver_rodas4 and solver_ros34pw2)
__all__ = ["FD_EPS", "H_KEEP", "H_MIN_REL", "INVALID", "JAC_MAX_AGE", "LU_MAX_MULT", "MAX_STEPS", "METHODS", "NON_FINITE",
           "OK", "RHS", "RODAS4", "ROS34PW2", "STALLED", "STATUS_TEXT", "STEP_UNDERFLOW", "WALL_TIME", "RunStats",
           "Sparsity", "_it_factor", "_it_solve", "colouring", "fd_jacobian", "integrate", "integrate_batch", "lu_plan",
           "probe_sparsity", "rhs_signature", "rodas4", "ros34pw2", "step_chunk"]
