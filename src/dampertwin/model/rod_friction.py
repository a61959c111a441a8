"""Rod friction: LuGre with Stribeck effect (thesis 4.6, eq. 4.38-4.41).

dv is the extension rate of the damper [m/s]; the force [N] is positive
when it resists extension (rebound), THESIS-ERRATA 6.
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter, State, index_enum
from .numerics import power
from .rod_friction_asymmetric import film_levels
from .seal_friction_pressure import pressure_friction

PARAMETERS = (
    Parameter("FR_FC", "N", "rod_friction.F_c", "Coulomb friction level, eq. 4.41"),
    Parameter("FR_FS", "N", "rod_friction.F_s", "static (Stribeck) friction level, eq. 4.41"),
    Parameter("FR_KB", "N/m", "rod_friction.k_b", "bristle stiffness, eq. 4.38"),
    Parameter("FR_S2", "N s/m", "constants.s2", "viscous friction, eq. 4.38"),
    Parameter("FR_CCOMP", "N s/m", "constants.c_comp", "bristle damping, eq. 4.39"),
    Parameter("FR_VD", "m/s", "constants.vd", "velocity scale of the bristle damping, eq. 4.39"),
    Parameter("FR_AS", "m/s", "constants.a_s", "Stribeck velocity, eq. 4.41"),
    Parameter("FR_ALPHAS", "-", "constants.alpha_s", "Stribeck exponent, eq. 4.41"),
    Parameter("E_ROD_FRICTION", "-", "effects.rod_friction", "switch: LuGre rod friction"),
)

STATES = (State("z", "m", 1e-5, 0.0, "LuGre bristle deflection, eq. 4.40"),)
Z = index_enum("Z", [s.name for s in STATES], __name__)  # offsets inside this submodel's state block


@njit(cache=True, error_model="numpy")
def stribeck(dv, F_c, F_s, a_s, alpha_s):
    """g(dv) = F_c + (F_s - F_c) exp(-(|dv|/a_s)^alpha_s), eq. 4.41 (errata 34)."""
    return F_c + (F_s - F_c) * math.exp(-power(abs(dv) / a_s, alpha_s))


@njit(cache=True, error_model="numpy")
def lugre(z, dv, k_b, F_c, F_s, s2, c_comp, vd, a_s, alpha_s):
    """Bristle rate dz/dt (eq. 4.40) and friction force (eq. 4.38, 4.39).
    Returns (dz/dt [m/s], F [N])."""
    g = stribeck(dv, F_c, F_s, a_s, alpha_s)
    dz = dv - k_b * abs(dv) / g * z
    s1 = c_comp * math.exp(-((dv / vd) ** 2))
    return dz, k_b * z + s1 * dz + s2 * dv


@njit(cache=True, error_model="numpy", inline="always")
def friction(y, o, p, dv, dy, P_r):
    """The rod-friction submodel in the assembled model: friction force [N]
    at extension rate dv [m/s] and rebound pressure P_r [Pa]; writes its
    state rates into dy[o + Z.*] (o: where the configuration placed this
    submodel's states). The effect rod_friction_asymmetric scales the
    velocity-dependent parts (F_s - F_c, s2) by direction,
    seal_friction_pressure raises the levels F_c, F_s of eq. 4.41."""
    if p[_L.P.E_ROD_FRICTION] > 0.5:
        F_c = p[_L.P.FR_FC]
        F_s = p[_L.P.FR_FS]
        s2 = p[_L.P.FR_S2]
        if p[_L.P.E_RF_ASYM] > 0.5:
            F_s, s2 = film_levels(p[_L.P.RFA_A], dv, p[_L.P.RFA_VREG], F_c, F_s, s2)
        if p[_L.P.E_SEAL_P] > 0.5:
            dF = pressure_friction(p[_L.P.SFP_KP], P_r, p[_L.P.P_ATM], p[_L.P.SFP_PREG])
            F_c += dF
            F_s += dF
        dz, F = lugre(y[o + Z.z], dv, p[_L.P.FR_KB], F_c, F_s, s2,
                      p[_L.P.FR_CCOMP], p[_L.P.FR_VD], p[_L.P.FR_AS], p[_L.P.FR_ALPHAS])
        dy[o + Z.z] = dz
        return F
    dy[o + Z.z] = 0.0
    return 0.0


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
