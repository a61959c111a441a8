"""The active valve's coil and current driver: the current that magnetises the
valve lags the commanded one (thesis 7.3, first discrepancy, the active
valve's dynamics; not in the thesis model, whose P/Q map is read at the
commanded current; off in the baseline design).

INVISIBLE IN EVERY STANDARD TEST: the protocols hold the current constant
for the whole record (the driver has settled before it starts), so the
effective current equals the commanded one at every instant and the effect
changes nothing there. It shows only when the command steps, e.g.
``simulate(..., current_before=I0, current_step_time=t1)``: the command is
I0 (on which the driver has settled before the record) until t1 [s], then
``current``.

Two first-order stages (states in A, both starting at the current before
the step):

- the current driver with the coil: a closed current loop of time constant
  tau_d whose rate is limited by the supply voltage over the coil's
  inductance, smoothly, di/dt = r_max tanh((I_cmd - i) / (tau_d r_max))
  (a first-order actuator model with a bandwidth and a rate limit:
  Savaresi et al., Semi-Active Suspension Control Design for Vehicles,
  2010, ch. 2; the rate limit di/dt <= U / L of an R-L coil);
- eddy currents in the solid iron delay the flux behind the coil current:
  tau_e dI_eff/dt = i - I_eff, the magnetising (effective) current I_eff
  (magnetic diffusion as a first-order lag, the diffusion resistor in
  parallel with the coil's inductance: Brauer, Magnetic Actuators and
  Sensors, 2nd ed., 2014, ch. 9).

The valve's P/Q map, its opening (active_valve_lag) and its spool friction
(valve_friction_current) are read at I_eff instead of the command. Two
states, in the extended configurations only (layout.variant).
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter, State

PARAMETERS = (
    Parameter("DRV_TAU", "s", "active_valve_driver.tau_d", "time constant of the current loop"),
    Parameter("DRV_RATE", "A/s", "active_valve_driver.rate_max", "largest current rate (supply voltage / inductance)"),
    Parameter("DRV_TAU_E", "s", "active_valve_driver.tau_e", "eddy-current lag of the magnetising current"),
    Parameter("CURRENT0", "A", None, "current commanded before the step (test condition)"),
    Parameter("T_STEP", "s", None, "time of the current step to CURRENT (test condition)"),
    Parameter("E_AV_DRIVER", "-", "effects.active_valve_driver", "switch: coil and current-driver dynamics"),
)

STATES = (
    State("i_coil", "A", 0.1, lambda q: q["CURRENT0"], "coil current behind the driver"),
    State("i_eff", "A", 0.1, lambda q: q["CURRENT0"], "magnetising (effective) current behind the eddy currents"),
)


@njit(cache=True, error_model="numpy")
def driver_rates(i, i_eff, i_cmd, tau_d, rate_max, tau_e):
    """(di/dt, dI_eff/dt) [A/s] of the driven coil and of the magnetising current."""
    di = rate_max * math.tanh((i_cmd - i) / (tau_d * rate_max))
    return di, (i - i_eff) / tau_e


@njit(cache=True, error_model="numpy", inline="always")
def effective_current(t, y, o, p, dy):
    """The current the valve sees [A] at time t [s] (states at y[o], y[o + 1];
    rates written); the commanded p[P.CURRENT] when off."""
    if p[_L.P.E_AV_DRIVER] > 0.5:
        i_cmd = p[_L.P.CURRENT0] if t < p[_L.P.T_STEP] else p[_L.P.CURRENT]
        dy[o], dy[o + 1] = driver_rates(y[o], y[o + 1], i_cmd, p[_L.P.DRV_TAU], p[_L.P.DRV_RATE],
                                        p[_L.P.DRV_TAU_E])
        return y[o + 1]
    dy[o] = 0.0
    dy[o + 1] = 0.0
    return p[_L.P.CURRENT]


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
