"""Active (CES-type) valve: data-based P/Q look-up table (thesis 4.4,
design parameter no. 52). Q(I, dp) bilinear on the map grid, current and dp
clamped to the grid, odd in dp (THESIS-ERRATA 30)."""

from __future__ import annotations

from numba import njit


@njit(cache=True)
def _bracket(grid, v):
    """Index i and weight w with v = (1-w) grid[i] + w grid[i+1], clamped."""
    n = grid.shape[0]
    if v <= grid[0]:
        return 0, 0.0
    if v >= grid[n - 1]:
        return n - 2, 1.0
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if grid[mid] <= v:
            lo = mid
        else:
            hi = mid
    return lo, (v - grid[lo]) / (grid[lo + 1] - grid[lo])


@njit(cache=True)
def active_valve_flow(current, dp, currents, dps, flow):
    """Flow [m^3/s] from the third tube to the reserve at pressure drop dp [Pa]
    and current [A]; flow[i, j] is the map at currents[i], dps[j]."""
    s = 1.0
    if dp < 0.0:
        s = -1.0
        dp = -dp
    i, wi = _bracket(currents, current)
    j, wj = _bracket(dps, dp)
    q0 = (1.0 - wj) * flow[i, j] + wj * flow[i, j + 1]
    q1 = (1.0 - wj) * flow[i + 1, j] + wj * flow[i + 1, j + 1]
    return s * ((1.0 - wi) * q0 + wi * q1)
