"""The integrator's shared parts (dampertwin.solver): the right-hand-side
signature, the method and status codes, the step controller's constants,
the numba flags and the scaled right-hand side."""

from __future__ import annotations

from .numba_cache import configure as _configure_cache

_configure_cache()  # before the first cached function below (also when only the solver is imported)

import numpy as np  # noqa: E402
from numba import njit, types  # noqa: E402


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
# Functions that allocate nothing compile without numba's reference counting: with it, every call that
# passes arrays (the RHS, ~43,000 calls a simulated second) paid 8 atomic increments and decrements, 16 % of
# the CPU time of bench/solver.py (perf); the step loops take their work arrays from :func:`work_arrays`.
_JIT_NO_NRT = dict(_JIT, _nrt=False)


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


@njit(inline="always", **_JIT)
def work_arrays(z, sc, n_rows, n_rhs_out):
    """Work arrays of a step loop for the n states of z: w [n_rows + 1, n]
    (row 0 holds 1/sc), the LU storage a [n, n], its pivots and the RHS's
    output vector (length n_rhs_out)."""
    n = z.shape[0]
    w = np.empty((n_rows + 1, n))
    for i in range(n):
        w[0, i] = 1.0 / sc[i]
    return w, np.empty((n, n)), np.empty(n, np.int64), np.empty(n_rhs_out)


_STEP_SIG = types.UniTuple(types.float64, 3)(
    RHS, _A1, types.float64, types.float64, types.float64, _A1, _A2, _A1, _A1, types.float64, types.float64,
    types.float64, _A1, types.int64, _A2, _I1, _A1, types.int64[::1], types.int64, _I1, types.int64, _I1, _I1,
    _I1, types.int64, types.float64, _A2, _A1)
