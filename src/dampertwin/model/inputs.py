"""The prescribed input of a test (displacement, flow or deflection),
sampled on a uniform grid and interpolated inside the compiled model."""

from __future__ import annotations

from numba import njit

from .declarations import Parameter

PARAMETERS = (
    Parameter("EX_T0", "s", None, "time of the first excitation sample"),
    Parameter("EX_DT", "s", None, "excitation sample spacing"),
)


@njit(cache=True, error_model="numpy", inline="always")
def hermite(t, t0, dt, ex):
    """Input and its rate at t: cubic Hermite through samples ex[0] (value)
    and ex[1] (rate) spaced dt from t0; held outside the record."""
    n = ex.shape[1]
    r = (t - t0) / dt
    if r <= 0.0:
        return ex[0, 0], ex[1, 0]
    k = int(r)
    if k >= n - 1:
        if r <= n - 1 + 1e-9:  # the last sample itself
            return ex[0, n - 1], ex[1, n - 1]
        return ex[0, n - 1], 0.0
    s = r - k
    s2 = s * s
    s3 = s2 * s
    u0 = ex[0, k]
    u1 = ex[0, k + 1]
    m0 = ex[1, k] * dt
    m1 = ex[1, k + 1] * dt
    u = (2 * s3 - 3 * s2 + 1) * u0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * u1 + (s3 - s2) * m1
    du = ((6 * s2 - 6 * s) * u0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * u1 + (3 * s2 - 2 * s) * m1) / dt
    return u, du
