"""Direction-dependent rod seal friction of the lubricating film (not in the
thesis model, whose LuGre friction eq. 4.38-4.41 is symmetric; not named by
the thesis; off in the baseline design).

Why not a direction-dependent Coulomb level: with levels F_c (1 + a) in
rebound and F_c (1 - a) in compression the sliding friction is
F_c sign(v) + a F_c, a symmetric friction plus a constant offset a F_c, the
same as a change of the precharge or of the load cell's offset (degenerate
with calibrated parameters). The boundary (Coulomb) level is set by the
lip's radial load, the same both ways; what differs with the direction is
the lubricating film: the lip's two flanks have different contact-pressure
gradients, so inverse hydrodynamic lubrication gives a thicker film, and a
different shear, in one direction than in the other (Mueller & Nau, Fluid
Sealing Technology, 1998, ch. 9; Nikas, Proc. IMechE J 224 (2010) 1-23,
reciprocating rod seals). The velocity-dependent parts of eq. 4.38 / 4.41,
the Stribeck excess F_s - F_c and the viscous friction s2, are scaled by
f(v) = 1 + a tanh(v / v_reg) [-] ((1 + a) in rebound, (1 - a) in
compression, switched smoothly over the named regularisation velocity v_reg
[m/s]; direction-dependent LuGre parameters: Olsson et al., Eur. J. Control
4 (1998) 176-195, sec. 3.6). While sliding the added force is
a [(F_s - F_c) exp(-(|v|/a_s)^alpha_s) + s2 |v|], even in v and growing with
the speed: no offset, no symmetric friction level reproduces it.
Acts only with the rod_friction effect on (a design switching it on without
rod_friction is refused: schema.EFFECT_NEEDS).
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter

PARAMETERS = (
    Parameter("RFA_A", "-", "rod_friction_asymmetric.a", "film friction asymmetry rebound vs compression"),
    Parameter("RFA_VREG", "m/s", "rod_friction_asymmetric.v_reg", "regularisation velocity of the switch"),
    Parameter("E_RF_ASYM", "-", "effects.rod_friction_asymmetric", "switch: asymmetric rod friction"),
)


@njit(cache=True, error_model="numpy")
def direction_factor(a, dv, v_reg):
    """f = 1 + a tanh(dv / v_reg) [-], dv the extension rate [m/s]."""
    return 1.0 + a * math.tanh(dv / v_reg)


@njit(cache=True, error_model="numpy")
def film_levels(a, dv, v_reg, F_c, F_s, s2):
    """Static level F_c + (F_s - F_c) f [N] and viscous coefficient s2 f
    [N s/m] at the extension rate dv [m/s]; the Coulomb level F_c stays."""
    f = direction_factor(a, dv, v_reg)
    return F_c + (F_s - F_c) * f, s2 * f


from . import layout as _L  # noqa: E402,F401  (bottom: layout reads this file's declarations first)
