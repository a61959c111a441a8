"""Active (CES-type) valve: data-based P/Q look-up table (thesis 4.4,
design parameter no. 52). Q(I, dp) bilinear on the map grid, current and dp
clamped to the grid, odd in dp (THESIS-ERRATA 30)."""

from __future__ import annotations

import numpy as np
import math

from numba import njit

from .declarations import Parameter

PARAMETERS = (Parameter("CURRENT", "A", None, "active-valve current (test condition)"),)

# The valve's opening as an orifice conductance G [m^3/(s Pa^0.5)]: Q = G r(dp) with the rounded
# orifice root r(dp) = dp / (dp^2 + DP_ROOT^2)^(1/4) (sign(dp) sqrt|dp| above DP_ROOT, laminar-like
# below; Merritt, Hydraulic Control Systems, 1967, ch. 3, for the orifice law).
DP_ROOT = 2.0e4  # [Pa] rounding of the orifice root at dp = 0 (0.2 bar: the map's first, linear, interval)
DP_SMALL = 1.0   # [Pa] below it the map's secant Q/dp is taken at DP_SMALL (the map is linear there)


def pack_map(currents, dps, flow) -> np.ndarray:
    """The P/Q map as the model's auxiliary data vector:
    [n_i, n_j, currents (n_i), dps (n_j), flow (n_i x n_j, row-major)]."""
    currents, dps, flow = (np.asarray(a, float) for a in (currents, dps, flow))
    return np.concatenate([[len(currents), len(dps)], currents, dps, flow.ravel()])


@njit(cache=True, error_model="numpy", inline="always")
def map_flow(current, dp, aux):
    """Flow [m^3/s] from the third tube to the reserve at pressure drop dp
    [Pa] and current [A], bilinear on the map packed by :func:`pack_map`
    (clamped to the grid, odd in dp)."""
    ni = int(aux[0])
    nj = int(aux[1])
    s = 1.0
    if dp < 0.0:
        s = -1.0
        dp = -dp
    i, wi = _bracket(aux, 2, ni, current)  # the grids read in place: a slice costs a reference count per call
    j, wj = _bracket(aux, 2 + ni, nj, dp)
    f = 2 + ni + nj  # flow[i, j] at aux[f + i nj + j] (row-major; no reshape per call)
    q0 = (1.0 - wj) * aux[f + i * nj + j] + wj * aux[f + i * nj + j + 1]
    q1 = (1.0 - wj) * aux[f + (i + 1) * nj + j] + wj * aux[f + (i + 1) * nj + j + 1]
    return s * ((1.0 - wi) * q0 + wi * q1)


@njit(cache=True, error_model="numpy", inline="always")
def _bracket(grid, o, n, v):
    """Index i and weight w with v = (1-w) g[i] + w g[i+1], clamped, on the
    grid g = grid[o:o + n]."""
    if v <= grid[o]:
        return 0, 0.0
    if v >= grid[o + n - 1]:
        return n - 2, 1.0
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if grid[o + mid] <= v:
            lo = mid
        else:
            hi = mid
    return lo, (v - grid[o + lo]) / (grid[o + lo + 1] - grid[o + lo])


def active_valve_flow(current, dp, currents, dps, flow) -> float:
    """Flow [m^3/s] from the third tube to the reserve at pressure drop dp [Pa]
    and current [A]; flow[i, j] is the map at currents[i], dps[j]. The
    model's own routine (:func:`map_flow`) on the packed map."""
    return float(map_flow(float(current), float(dp), pack_map(currents, dps, flow)))


@njit(cache=True, error_model="numpy", inline="always")
def commanded_current(p):
    """The test's active-valve current [A] (parameter CURRENT)."""
    return p[_L.P.CURRENT]


@njit(cache=True, error_model="numpy", inline="always")
def active_flow(p, aux, dp, current):
    """The active valve in the assembled model: flow [m^3/s] at dp [Pa] and
    the current [A] the valve sees (the test's, parameter CURRENT, unless
    active_valve_driver), map in ``aux``."""
    return map_flow(current, dp, aux)


@njit(cache=True, error_model="numpy", inline="always")
def _root_weight(dp):
    """(dp^2 + DP_ROOT^2)^(1/4) [Pa^0.5]: r(dp) = dp / _root_weight(dp)."""
    return math.sqrt(math.sqrt(dp * dp + DP_ROOT * DP_ROOT))


@njit(cache=True, error_model="numpy", inline="always")
def map_conductance(current, dp_open, aux):
    """The opening [m^3/(s Pa^0.5)] the static map holds at the pressure drop dp_open [Pa]:
    G = Q_map(I, dp_open) / r(dp_open) >= 0 (the map is odd and has the sign of dp)."""
    a = max(abs(dp_open), DP_SMALL)
    return map_flow(current, a, aux) / a * _root_weight(dp_open)


@njit(cache=True, error_model="numpy", inline="always")
def opening_flow(p, aux, dp_open, dp, Q_map, current):
    """Flow [m^3/s] through the active valve held at the opening of the static map at dp_open,
    under the pressure drop dp [Pa]: G(I, dp_open) r(dp). Its sign is that of dp whatever
    dp_open (passive: Q dp >= 0); at dp_open = dp it is the map's flow (|dp| >= DP_SMALL), and
    then the map's own value Q_map is returned (bit-identical when the effects are off).
    ``current`` [A]: the current the valve sees."""
    if dp_open == dp:
        return Q_map
    return map_conductance(current, dp_open, aux) * dp / _root_weight(dp)


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
