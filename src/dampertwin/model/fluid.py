"""Hydraulic medium and structure compliance (thesis 4.3, eq. 4.13-4.18).

All pressures absolute [Pa], volumes [m^3], moduli [Pa].
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter

PARAMETERS = (
    Parameter("K_OIL", "Pa", "oil.K_oil", "bulk modulus of gas-free oil"),
    Parameter("RHO", "kg/m^3", "oil.rho_oil", "oil density"),
    Parameter("NU", "m^2/s", "oil.nu", "kinematic viscosity"),
    Parameter("P_SAT", "Pa", "oil.P_sat", "saturation pressure (all gas dissolved above), eq. 4.14"),
    Parameter("P_VAP", "Pa", "oil.P_vap", "vapour pressure, eq. 4.14"),
    Parameter("CHI", "-", "oil.chi", "gas volume fraction at P_ref, eq. 4.15"),
    Parameter("GAMMA", "-", "oil.Gamma", "polytropic exponent"),
    Parameter("TEMP", "K", "oil.T", "oil temperature"),
    Parameter("P_REF", "Pa", "constants.P_ref", "reference pressure of chi"),
    Parameter("T_REF", "K", "constants.T_ref", "reference temperature of chi"),
    Parameter("RHO_GAS", "kg/m^3", "constants.rho_gas", "gas density at the reference state"),
    Parameter("PSI_PT", "1/Pa", lambda d: wall_compliance(d["third_tube.E"], d["third_tube.nu_p"],
                                                         d.constant("pt_r_i"), d.constant("pt_r_o")),
              "pressure-tube wall compliance, eq. 4.17"),
    Parameter("PSI_TT", "1/Pa", lambda d: wall_compliance(d["third_tube.E"], d["third_tube.nu_p"],
                                                         d["third_tube.r_i"], d["third_tube.r_o"]),
              "third-tube wall compliance, eq. 4.17"),
    Parameter("RATIO_TT", "-", "constants.wall_ratio_third_tube", "enclosed / chamber volume of the third tube"),
    Parameter("E_GAS", "-", "effects.gas_content", "switch: emulsion modulus eq. 4.14-4.16"),
    Parameter("E_WALL", "-", "effects.wall_compliance", "switch: wall compliance eq. 4.13, 4.17-4.18"),
)

# Below this pressure the gas law of eq. 4.15 is evaluated at this floor
# (the emulsion is then all gas-and-vapour; avoids P -> 0 in (P_ref/P)^(1/G)).
P_FLOOR = 100.0  # [Pa]


# Regularisation REG-1 (not in the thesis): the undissolved gas share of
# eq. 4.14 is clipped to [0, 1] with kinks at P_vap and P_sat, so the emulsion
# modulus jumps there (4.98e8 -> 7.7e8 Pa at P_sat = 10 bar) and the
# integrator rejects a step at every crossing (~25 per second at 13 Hz). The
# clip is blended over +-SAT_BLEND around each kink (quadratic, C1): theta,
# and so K, is exactly the sharp law outside the bands. SAT_BLEND = 0 gives
# the sharp law.
SAT_BLEND = 0.5e5  # [Pa]


@njit(cache=True, error_model="numpy")
def _ramp(x, w):
    """max(x, 0), blended quadratically over |x| < w (C1). Returns (value, slope)."""
    if x <= -w:
        return 0.0, 0.0
    if x >= w:
        return x, 1.0
    return (x + w) * (x + w) / (4.0 * w), (x + w) / (2.0 * w)


@njit(cache=True, error_model="numpy")
def gas_fraction(P, P_sat, P_vap, blend=SAT_BLEND):
    """Undissolved share theta of the gas, eq. 4.14, clipped to [0, 1]
    (THESIS-ERRATA 10) with the REG-1 blend of half-width ``blend`` [Pa]:
    theta = [ramp(P_sat - P) - ramp(P_vap - P)] / (P_sat - P_vap).
    Returns (theta, dtheta/dP)."""
    span = P_sat - P_vap
    w = min(blend, 0.25 * span)
    if w <= 0.0 or (P_vap + w <= P <= P_sat - w) or P >= P_sat + w or P <= P_vap - w:
        th = 1.0 - (P - P_vap) / span  # the sharp law, exactly
        if th >= 1.0:
            return 1.0, 0.0
        if th <= 0.0:
            return 0.0, 0.0
        return th, -1.0 / span
    r1, s1 = _ramp(P_sat - P, w)
    r2, s2 = _ramp(P_vap - P, w)
    return (r1 - r2) / span, (s2 - s1) / span


@njit(cache=True, error_model="numpy")
def emulsion_denominator(P, K_oil, chi, P_sat, P_vap, P_ref, T, T_ref, Gamma):
    """Denominator D(P) of eq. 4.15 and dD/dP: rho_eml = rho_ref_mix / D."""
    P = max(P, P_FLOOR)
    e = math.exp(-(P - P_ref) / K_oil)
    th, dth = gas_fraction(P, P_sat, P_vap)
    if th == 0.0 and dth == 0.0:  # all gas dissolved: the gas terms are exact zeros, skip their pow call
        return (1.0 - chi) * e, -(1.0 - chi) * e / K_oil
    g = (P_ref / P) ** (1.0 / Gamma)
    tt = chi * T / T_ref
    D = (1.0 - chi) * e + th * tt * g
    dD = -(1.0 - chi) * e / K_oil + tt * (dth * g - th * g / (Gamma * P))
    return D, dD


@njit(cache=True, error_model="numpy")
def emulsion_density(P, rho_oil, rho_gas, K_oil, chi, P_sat, P_vap, P_ref, T, T_ref, Gamma):
    """Emulsion density, eq. 4.15 [kg/m^3]."""
    D, _ = emulsion_denominator(P, K_oil, chi, P_sat, P_vap, P_ref, T, T_ref, Gamma)
    return ((1.0 - chi) * rho_oil + chi * rho_gas) / D


@njit(cache=True, error_model="numpy")
def emulsion_bulk_modulus(P, K_oil, chi, P_sat, P_vap, P_ref, T, T_ref, Gamma):
    """K_eml = rho dP/drho, eq. 4.16, from the full derivative of eq. 4.15
    including the Henry's-law dissolution term (THESIS-ERRATA 11): K = -D/D'."""
    if chi <= 0.0:
        return K_oil
    D, dD = emulsion_denominator(P, K_oil, chi, P_sat, P_vap, P_ref, T, T_ref, Gamma)
    return -D / dD


@njit(cache=True, error_model="numpy")
def wall_compliance(E, nu, r_i, r_o):
    """Volumetric compliance psi [1/Pa] of a thick-walled closed tube, eq. 4.17
    in Lame's form (THESIS-ERRATA 14): hoop + axial strain of the bore."""
    ri2 = r_i * r_i
    ro2 = r_o * r_o
    return 2.0 / E * ((ro2 + ri2) / (ro2 - ri2) + nu - nu * ri2 / (ro2 - ri2))


@njit(cache=True, error_model="numpy")
def wall_compliance_literal(E, nu, r_i, r_o):
    """Eq. 4.17 exactly as printed (last denominator r_o^2 + r_i^2)."""
    ri2 = r_i * r_i
    ro2 = r_o * r_o
    return 2.0 / E * ((ro2 + ri2) / (ro2 - ri2) + nu) - 2.0 / E * nu * ri2 / (ro2 + ri2)


@njit(cache=True, error_model="numpy")
def wall_bulk_modulus(psi, dP, volume_ratio):
    """Wall bulk modulus, eq. 4.18, K_wall = (1 + psi dP)/psi, with dP the
    pressure difference across the wall; divided by V_enclosed/V_chamber for
    an annular chamber (THESIS-ERRATA 15; 1.0 = thesis literal)."""
    return (1.0 + psi * dP) / psi / volume_ratio


@njit(cache=True, error_model="numpy")
def series_bulk_modulus(K_a, K_b):
    """Total modulus of two compliances in series, eq. 4.13."""
    return 1.0 / (1.0 / K_a + 1.0 / K_b)


@njit(cache=True, error_model="numpy")
def gas_spring_pressure(P0, V0, V, Gamma):
    """Reserve-chamber gas pressure, polytropic from the precharge
    (THESIS-ERRATA 8): P = P0 (V0/V)^Gamma."""
    return P0 * (V0 / V) ** Gamma
