"""Dynamics of the active valve's opening that its static P/Q map cannot
capture (thesis 7.3, first discrepancy: at low current and high velocity,
"the look-up-table approach ... is not able to capture the dynamic behavior
of the active valve"; not in the thesis model; off in the baseline design).

The valve's solenoid (R-L coil with eddy currents), its pilot stage and the
main stage filling its control chamber need time to reach the opening that
the static map assumes. The OPENING lags, not the flow: the opening is the
map's opening G(I, p_o) at an opening pressure p_o [Pa] that follows the
pressure drop dp with a first-order lag of time constant tau [s],

    tau dp_o/dt = dp - p_o,       Q_a = G(I, p_o) r(dp),

G = Q_map / r >= 0 the map's orifice conductance and r(dp) the rounded
orifice root (active_valve.opening_flow). The flow therefore always has the
sign of its pressure drop (Q_a dp >= 0: the valve stays passive, which a lag
of the flow itself broke), and tau -> 0 gives the static map. First-order
response of a semi-active damper's damping coefficient (an opening, >= 0) to
its command: Savaresi et al., Semi-Active Suspension Control Design for
Vehicles, 2010, ch. 2. The current is constant in every test, so a lag of the
effective current alone would be invisible there; the lag acts on the
opening's response to the pressure (the main stage following its pilot).
One state, p_open, in the extended configurations only (layout.variant).
"""

from __future__ import annotations

from numba import njit

from .declarations import Parameter, State

PARAMETERS = (
    Parameter("AV_TAU", "s", "active_valve_lag.tau", "time constant of the active valve's opening"),
    Parameter("E_AV_LAG", "-", "effects.active_valve_lag", "switch: active-valve opening lag (a state)"),
)

# rest: no pressure drop across the valve (third tube and reserve both at the precharge)
STATES = (State("p_open", "Pa", 1e5, 0.0, "pressure drop the active valve's opening has reached (lag)"),)


@njit(cache=True, error_model="numpy")
def lag_rate(p_o, dp, tau):
    """dp_o/dt = (dp - p_o) / tau [Pa/s]."""
    return (dp - p_o) / tau


@njit(cache=True, error_model="numpy", inline="always")
def opening_pressure(y, o, p, dp, dy):
    """The lag in the assembled (extended) model: returns the pressure drop
    [Pa] whose static opening the valve has (its state at y[o]) and writes
    dy[o]; ``dp`` itself when off."""
    if p[_L.P.E_AV_LAG] > 0.5:
        dy[o] = lag_rate(y[o], dp, p[_L.P.AV_TAU])
        return y[o]
    dy[o] = 0.0
    return dp


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
