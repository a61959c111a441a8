"""Reserve-chamber gas and the entrained gas of the truth.

Reserve: an ideal gas (nitrogen, gas constant R_S, c_v) of mass m_g and
temperature T_g above the reserve oil (mass m_res, incompressible at the
reserve's low pressure, expanding with temperature). First law for the open
gas volume: m_g c_v dT_g/dt = -P dV_g/dt - H (T_g - T_oil) + R_S T_g dm_g/dt;
the wall exchange H = m_g0 c_v / TAU_TH makes the gas spring polytropic
between isothermal (TAU_TH -> 0) and adiabatic (TAU_TH -> inf) (Lion &
Loose, Technische Mechanik 22 (2002); Pourmovahed & Otis, ASME J. Dyn. Syst.
Meas. Control 112 (1990) 413, thermal time constant of gas springs).
Dissolution into the reserve oil at a finite rate: the dissolved mass c
relaxes with TAU_S to Henry's equilibrium K_H P V_oil (Henry's law; Totten,
Handbook of Hydraulic Fluid Technology, 2000, ch. 6: air solubility in
mineral oil ~ 9 % by volume per bar).

Entrained gas in the working chambers: free gas g [m^3 at P_ref] per
chamber relaxes to the Henry equilibrium of the oil's total gas content,
released fast (TAU_REL) below it and dissolved slowly (TAU_DIS) above it
(Brennen, Cavitation and Bubble Dynamics, 1995, ch. 2-3); the bubbles are
isothermal. A floor of nuclei ALPHA_N stays free.
"""

from __future__ import annotations

from numba import njit

from .fluid import JIT, ramp

PARAMS = ("V_TOT", "R_S", "C_V", "H", "K_H", "TAU_S", "ALPHA_TOT", "S_H", "ALPHA_N", "TAU_REL", "TAU_DIS",
          "DISSOLVE", "HEAT")
V_TOT, R_S, C_V, H, K_H, TAU_S, ALPHA_TOT, S_H, ALPHA_N, TAU_REL, TAU_DIS, DISSOLVE, HEAT = range(len(PARAMS))
STATES = (("m_res", "kg", 1e-2, "reserve oil mass"), ("m_g", "kg", 1e-5, "reserve gas mass"),
          ("T_g", "K", 1.0, "reserve gas temperature"), ("c", "kg", 1e-6, "gas dissolved in the reserve oil"))
M_RES, M_G, T_G, C = range(len(STATES))
ALPHA_EPS = 1e-4  # [-] rounding of the free-gas equilibrium at full dissolution


@njit(**JIT)
def reserve_pressure(y, s, p, o, V_oil, V_swept):
    """Gas pressure [Pa] and gas volume [m^3] of the reserve."""
    V_g = p[o + V_TOT] - V_oil - V_swept
    return y[s + M_G] * p[o + R_S] * y[s + T_G] / V_g, V_g


@njit(**JIT)
def reserve(y, s, p, o, P, V_g, dV_g, V_oil, T_oil, dy):
    """Writes the gas's state rates for the gas volume's rate dV_g [m^3/s]
    (the caller writes dm_res); returns the heat leaving the gas [W]."""
    m = y[s + M_G]
    T = y[s + T_G]
    dc = 0.0
    if p[o + DISSOLVE] > 0.5:
        dc = (p[o + K_H] * P * V_oil - y[s + C]) / p[o + TAU_S]
    dm = -dc
    q = p[o + H] * (T - T_oil) if p[o + HEAT] > 0.5 else 0.0
    dy[s + M_G] = dm
    dy[s + C] = dc
    dy[s + T_G] = (-P * dV_g - q + p[o + R_S] * T * dm) / (m * p[o + C_V])
    return q


@njit(**JIT)
def free_gas_rate(g, P, V_liq, P_ref, p, o):
    """d g / dt [m^3/s at P_ref] of a chamber's entrained gas at pressure P."""
    if p[o + DISSOLVE] < 0.5:
        return 0.0
    eq = V_liq * (p[o + ALPHA_N] + ramp(p[o + ALPHA_TOT] - p[o + S_H] * P / P_ref, ALPHA_EPS))
    tau = p[o + TAU_REL] if eq > g else p[o + TAU_DIS]
    return (eq - g) / tau


def equilibrium_free_gas(alpha_free: float, P: float, p_gas: dict, P_ref: float) -> float:
    """Total gas content ALPHA_TOT [-] that makes ``alpha_free`` [-] (free
    gas per liquid volume at P_ref) the equilibrium at pressure P."""
    return alpha_free - p_gas["ALPHA_N"] + p_gas["S_H"] * P / P_ref
