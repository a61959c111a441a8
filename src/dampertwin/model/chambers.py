"""Chambers and rod force (thesis 4.1-4.2, eq. 4.1-4.12).

Sign convention (THESIS-ERRATA 3): stroke s > 0 is extension (rebound): the
rebound volume shrinks, the compression volume grows. Pressures absolute.
"""

from __future__ import annotations

import math

from numba import njit

from ..design.architecture import ARCHITECTURES
from .declarations import Parameter, State
from .fluid import emulsion_bulk_modulus, series_bulk_modulus, wall_bulk_modulus

PARAMETERS = (
    Parameter("A_R", "m^2", lambda d: math.pi * (d["geometry.D_PT"] ** 2 - d["geometry.D_R"] ** 2) / 4.0,
              "rebound (annulus) area, eq. 4.2"),
    Parameter("A_B", "m^2", lambda d: math.pi * d["geometry.D_PT"] ** 2 / 4.0, "piston (bore) area, eq. 4.3"),
    Parameter("L_R0", "m", "geometry.l_r0", "rebound chamber length at zero stroke"),
    Parameter("L_C0", "m", "geometry.l_c0", "compression chamber length at zero stroke"),
    Parameter("V_B", "m^3", "geometry.V_b", "third-tube chamber volume"),
    Parameter("P_ATM", "Pa", "constants.P_atm", "atmospheric pressure"),
    Parameter("P0", "Pa", "oil.P_0", "precharge pressure (absolute)"),
    Parameter("V_G0", "m^3", "constants.V_gas0", "reserve gas volume at the precharge"),
    Parameter("E_CAV", "-", "effects.cavitation", "switch: cavitation floor of the chamber modulus"),
    Parameter("ARCH", "-", lambda d: ARCHITECTURES[d.architecture],
              "architecture: 0 triple tube semi-active, 1 twin tube, 2 mono tube (design/architecture.py)"),
)
TWIN_TUBE, MONO_TUBE = ARCHITECTURES["twin_tube"], ARCHITECTURES["mono_tube"]

STATES = (
    State("P_r", "Pa", 1e5, lambda q: q["P0"], "rebound chamber pressure, eq. 4.10"),
    State("P_c", "Pa", 1e5, lambda q: q["P0"], "compression chamber pressure, eq. 4.11"),
    State("P_b", "Pa", 1e5, lambda q: q["P0"], "third-tube pressure, eq. 4.12"),
    State("V_g", "m^3", 1e-5, lambda q: q["V_G0"], "reserve gas volume (THESIS-ERRATA 8)"),
)

# Cavitation: the effective modulus fades to CAV_MIN of its value as the
# pressure falls to the vapour pressure over CAV_BAND, and decays
# exponentially (rate CAV_DECAY per band) below it, so a chamber is not pulled
# below P_vap (a vapour cavity forms instead) yet always recovers.
CAV_BAND = 0.3e5  # [Pa]
CAV_MIN = 1e-3
CAV_DECAY = 5.0


@njit(cache=True, error_model="numpy")
def chamber_volumes(s, A_r, A_b, l_r0, l_c0):
    """Rebound and compression volumes, eq. 4.5-4.6 (A_c read as A_b, errata 4)."""
    return A_r * (l_r0 - s), A_b * (l_c0 + s)


@njit(cache=True, error_model="numpy")
def cavitation_factor(P, P_vap):
    """Smooth factor in [CAV_MIN, 1] scaling the modulus near P_vap."""
    u = (P - P_vap) / CAV_BAND
    if u >= 1.0:
        return 1.0
    if u <= 0.0:
        return CAV_MIN * math.exp(CAV_DECAY * u)
    return CAV_MIN + (1.0 - CAV_MIN) * u * u * (3.0 - 2.0 * u)


@njit(cache=True, error_model="numpy")
def pressure_rate(K, V, dV, Q_out):
    """dP/dt = -K/V (dV/dt + Q_out), eq. 4.9-4.12, Q_out the net outflow."""
    return -K / V * (dV + Q_out)


@njit(cache=True, error_model="numpy", inline="always")
def floating_piston(K_c, V_c, dV_c, Q_out, P_gas, V_g, gamma, heating):
    """Mono tube: the compression chamber's oil (modulus K_c [Pa], volume V_c
    [m^3]) and the gas chamber (P_gas [Pa], V_g [m^3], polytropic index gamma)
    behind a massless, frictionless floating piston, so P_c = P_gas and their
    compliances c_oil = V_c / K_c and c_gas = V_g / (gamma P_gas) [m^3/Pa] add
    (eq. 4.9 with the gas spring of THESIS-ERRATA 8 in series; Talbott &
    Starkey 2002). dV_c [m^3/s]: the chamber's volume rate at a fixed floating
    piston; Q_out [m^3/s]: its net oil outflow; heating [Pa/s]: the gas's
    pressure rate at fixed volume (P_gas dT/dt / T with oil_thermal, else 0).
    Oil: c_oil dP = -(dV_c + Q_out) + dV_g; gas: dP = -dV_g / c_gas + heating.
    Returns (dP_c/dt [Pa/s], dV_g/dt [m^3/s])."""
    c_gas = V_g / (gamma * P_gas)
    c_oil = V_c / K_c
    dP = (-(dV_c + Q_out) + c_gas * heating) / (c_gas + c_oil)
    return dP, c_gas * (heating - dP)


@njit(cache=True, error_model="numpy")
def rod_force(P_r, P_c, A_r, A_b, P_atm, F_mu):
    """Force on the rod, eq. 4.1 from a free-body diagram (THESIS-ERRATA 1, 2):
    (P_r - P_atm) A_r - (P_c - P_atm) A_b + F_mu, A_r the annulus. Positive
    = tension (rebound) [N]."""
    return (P_r - P_atm) * A_r - (P_c - P_atm) * A_b + F_mu


@njit(cache=True, error_model="numpy", inline="always")
def oil_modulus(pressure, p, K_oil, T):
    """Emulsion modulus (eq. 4.14-4.16) at absolute pressure [Pa] for the
    gas-free oil's modulus K_oil [Pa] and the temperature T [K] (p[P.K_OIL],
    p[P.TEMP] unless oil_thermal), or K_oil when the gas-content effect is off."""
    if p[_L.P.E_GAS] > 0.5:
        return emulsion_bulk_modulus(pressure, K_oil, p[_L.P.CHI], p[_L.P.P_SAT], p[_L.P.P_VAP],
                                     p[_L.P.P_REF], T, p[_L.P.T_REF], p[_L.P.GAMMA])
    return K_oil


@njit(cache=True, error_model="numpy", inline="always")
def moduli(p, P_r, P_c, P_b, P_res, K_oil, T):
    """Effective moduli [Pa] of the rebound, compression and third-tube
    chambers: oil / emulsion (gas-free oil modulus K_oil [Pa], temperature
    T [K]), in series with the walls (eq. 4.13, 4.17-4.18), times the
    cavitation factor."""
    K_r = oil_modulus(P_r, p, K_oil, T)
    K_c = oil_modulus(P_c, p, K_oil, T)
    K_b = oil_modulus(P_b, p, K_oil, T)
    return structure(p, K_r, K_c, K_b, P_r, P_c, P_b, P_res)


@njit(cache=True, error_model="numpy", inline="always")
def structure(p, K_r, K_c, K_b, P_r, P_c, P_b, P_res):
    """Effective moduli [Pa] of the three chambers from their fluids' moduli
    K_r, K_c, K_b [Pa]: in series with the walls (eq. 4.13, 4.17-4.18), times
    the cavitation factor."""
    if p[_L.P.E_WALL] > 0.5:
        K_c = series_bulk_modulus(K_c, wall_bulk_modulus(p[_L.P.PSI_PT], P_c - P_res, 1.0))
        K_b = series_bulk_modulus(K_b, wall_bulk_modulus(p[_L.P.PSI_TT], P_b - P_res, p[_L.P.RATIO_TT]))
    if p[_L.P.E_CAV] > 0.5:
        K_r *= cavitation_factor(P_r, p[_L.P.P_VAP])
        K_c *= cavitation_factor(P_c, p[_L.P.P_VAP])
        K_b *= cavitation_factor(P_b, p[_L.P.P_VAP])
    return K_r, K_c, K_b


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
