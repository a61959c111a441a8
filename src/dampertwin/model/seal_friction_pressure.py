"""Rod seal friction growing with the rebound-chamber pressure (not in the
thesis model; off in the baseline design).

The rod seal is pressed onto the rod by the rebound-chamber gauge pressure,
so its Coulomb and static levels (eq. 4.41) grow by
dF = k_p r(P_r - P_atm) [N], k_p = mu pi D_R L_contact [N/Pa]
(reciprocating seal friction proportional to the sealed pressure: Mueller &
Nau, Fluid Sealing Technology, 1998, ch. 9), r the smooth ramp
(u + sqrt(u^2 + p_reg^2)) / 2 with the named regularisation p_reg [Pa].
Acts only with the rod_friction effect on (a design switching it on without
rod_friction is refused: schema.EFFECT_NEEDS).
"""

from __future__ import annotations

from numba import njit

from .declarations import Parameter
from .valve_friction_current import smooth_ramp

PARAMETERS = (
    Parameter("SFP_KP", "N/Pa", "seal_friction_pressure.k_p", "growth of the seal friction with pressure"),
    Parameter("SFP_PREG", "Pa", "seal_friction_pressure.p_reg", "regularisation of the gauge pressure"),
    Parameter("E_SEAL_P", "-", "effects.seal_friction_pressure", "switch: pressure-loaded rod seal"),
)


@njit(cache=True, error_model="numpy")
def pressure_friction(k_p, P_r, P_atm, p_reg):
    """Extra seal friction level [N] at rebound pressure P_r [Pa abs]."""
    return k_p * smooth_ramp(P_r - P_atm, p_reg)


from . import layout as _L  # noqa: E402,F401  (bottom: layout reads this file's declarations first)
