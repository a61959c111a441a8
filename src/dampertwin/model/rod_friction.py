"""Rod friction: LuGre with Stribeck effect (thesis 4.6, eq. 4.38-4.41).

dv is the extension rate of the damper [m/s]; the force [N] is positive
when it resists extension (rebound), THESIS-ERRATA 6.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def stribeck(dv, F_c, F_s, a_s, alpha_s):
    """g(dv) = F_c + (F_s - F_c) exp(-(|dv|/a_s)^alpha_s), eq. 4.41 (errata 34)."""
    return F_c + (F_s - F_c) * math.exp(-((abs(dv) / a_s) ** alpha_s))


@njit(cache=True)
def lugre(z, dv, k_b, F_c, F_s, s2, c_comp, vd, a_s, alpha_s):
    """Bristle rate dz/dt (eq. 4.40) and friction force (eq. 4.38, 4.39).
    Returns (dz/dt [m/s], F [N])."""
    g = stribeck(dv, F_c, F_s, a_s, alpha_s)
    dz = dv - k_b * abs(dv) / g * z
    s1 = c_comp * math.exp(-((dv / vd) ** 2))
    return dz, k_b * z + s1 * dz + s2 * dv
