"""Current-dependent friction of the active valve's spool (thesis 7.4; not in
the thesis model, whose P/Q map is friction-free; off in the baseline).

The spool's Coulomb friction F_f = F0 + k_I I [N] (the solenoid's radial
magnetic force presses the spool on its bore, so it grows with the current I)
must be overcome by the pressure on the spool area A_sp before the opening
follows the map: the map sees the pressure drop reduced by the friction
pressure dp_f = F_f / A_sp, with the sign of the flow, i.e. a dead band of
+-dp_f and a pressure hysteresis of 2 dp_f between opening and closing
(Coulomb spool friction, Manring, Hydraulic Control Systems, 2005, 4.6):
dp_eff = r(dp - dp_f) - r(-dp - dp_f), r(u) = (u + sqrt(u^2 + eps^2)) / 2,
the smooth ramp with the named regularisation eps = dp_reg [Pa] in place of
max(u, 0) (so no sign switch, no chattering).
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter

PARAMETERS = (
    Parameter("VF_F0", "N", "valve_friction_current.F0", "spool friction at zero current"),
    Parameter("VF_KI", "N/A", "valve_friction_current.k_I", "growth of the spool friction with current"),
    Parameter("VF_A", "m^2", "valve_friction_current.A_spool", "pressure-loaded spool area"),
    Parameter("VF_DPREG", "Pa", "valve_friction_current.dp_reg", "regularisation of the dead band"),
    Parameter("E_VALVE_FRICTION", "-", "effects.valve_friction_current", "switch: active-valve spool friction"),
)


@njit(cache=True, error_model="numpy")
def smooth_ramp(u, eps):
    """(u + sqrt(u^2 + eps^2)) / 2: max(u, 0) rounded over |u| ~ eps."""
    return 0.5 * (u + math.sqrt(u * u + eps * eps))


@njit(cache=True, error_model="numpy")
def dead_band(dp, dp_f, eps):
    """Pressure drop [Pa] left after the friction pressure dp_f: odd, monotone."""
    return smooth_ramp(dp - dp_f, eps) - smooth_ramp(-dp - dp_f, eps)


@njit(cache=True, error_model="numpy", inline="always")
def effective_drop(p, dp):
    """The pressure drop [Pa] the active valve's map sees (dp when off)."""
    if p[_L.P.E_VALVE_FRICTION] > 0.5:
        dp_f = (p[_L.P.VF_F0] + p[_L.P.VF_KI] * p[_L.P.CURRENT]) / p[_L.P.VF_A]
        return dead_band(dp, dp_f, p[_L.P.VF_DPREG])
    return dp


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
