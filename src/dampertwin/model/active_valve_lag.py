"""Dynamics of the active valve that its static P/Q map cannot capture
(thesis 7.4; not in the thesis model; off in the baseline design).

The solenoid, the pilot stage and the spool need time to reach the opening
that the static map assumes: the valve's effective flow Q_a [m^3/s] follows
the static map value Q_map(I, dp) with a first-order lag of time constant tau
[s], tau dQ_a/dt = Q_map - Q_a (first-order damper dynamics, Savaresi et al.,
Semi-Active Suspension Control Design for Vehicles, 2010, 2.3 eq. 2.9).
One state, Q_lag, in the extended configurations only (layout.variant).
"""

from __future__ import annotations

from numba import njit

from .declarations import Parameter, State

PARAMETERS = (
    Parameter("AV_TAU", "s", "active_valve_lag.tau", "time constant of the active valve's flow"),
    Parameter("E_AV_LAG", "-", "effects.active_valve_lag", "switch: active-valve lag (a state)"),
)

STATES = (State("Q_lag", "m^3/s", 1e-5, 0.0, "lagged flow of the active valve (third tube -> reserve)"),)


@njit(cache=True, error_model="numpy")
def lag_rate(Q, Q_map, tau):
    """dQ/dt = (Q_map - Q) / tau [m^3/s^2]."""
    return (Q_map - Q) / tau


@njit(cache=True, error_model="numpy", inline="always")
def lagged_flow(y, o, p, Q_map, dy):
    """The lag in the assembled (extended) model: returns the active valve's
    flow [m^3/s] and writes dy[o] (its state at y[o]); Q_map when off."""
    if p[_L.P.E_AV_LAG] > 0.5:
        dy[o] = lag_rate(y[o], Q_map, p[_L.P.AV_TAU])
        return y[o]
    dy[o] = 0.0
    return Q_map


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
