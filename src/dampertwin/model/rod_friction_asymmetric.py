"""Direction-dependent rod seal friction (not in the thesis model, whose
LuGre friction eq. 4.38-4.41 is symmetric; off in the baseline design).

A lip seal drags differently when the rod moves out (rebound) than in
(compression): the Coulomb and static levels of eq. 4.41 are scaled by
f(v) = 1 + a tanh(v / v_reg) [-], i.e. (1 + a) in rebound and (1 - a) in
compression, switched smoothly over the named regularisation velocity v_reg
[m/s] (direction-dependent LuGre parameters: Olsson et al., Eur. J. Control
4 (1998) 176-195, sec. 3.6). Acts only with the rod_friction effect on.
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter

PARAMETERS = (
    Parameter("RFA_A", "-", "rod_friction_asymmetric.a", "friction asymmetry rebound vs compression"),
    Parameter("RFA_VREG", "m/s", "rod_friction_asymmetric.v_reg", "regularisation velocity of the switch"),
    Parameter("E_RF_ASYM", "-", "effects.rod_friction_asymmetric", "switch: asymmetric rod friction"),
)


@njit(cache=True, error_model="numpy")
def direction_factor(a, dv, v_reg):
    """f = 1 + a tanh(dv / v_reg) [-], dv the extension rate [m/s]."""
    return 1.0 + a * math.tanh(dv / v_reg)


from . import layout as _L  # noqa: E402,F401  (bottom: layout reads this file's declarations first)
