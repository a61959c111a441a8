"""Chambers of the truth: mass-conservative pressure rates, wall
compliance, oil heating, and the passages between chambers.

Each chamber holds liquid oil (Murnaghan density, thermal expansion) and
entrained gas g [m^3 at P_ref] (isothermal bubbles, V_gas = g P_ref / P);
its walls stretch, V = V0 (1 + kappa (P - P_atm)), kappa from Lame's
formula (fluid.lame_compliance). The pressure rate follows from the oil
mass balance d(rho V_liq)/dt = mdot (the states are pressures; the mass
they imply is conserved, tests/test_truth_physics.py). The passages: the
bypass holes rebound -> third tube (laminar + turbulent), and the piston
band's clearance with Poiseuille and Couette flow and the shear it puts on
the piston (White, Viscous Fluid Flow, 3rd ed. 2006, 3-2). The oil's lumped
temperature rises with the dissipated power and loses HA (T - T_amb).
"""

from __future__ import annotations

import math

from numba import njit

from .fluid import BETA_T, JIT, P_ATM, P_FLOOR_EPS, P_REF, P_V, density, modulus, ramp, ramp_slope
from .fluid import throttle as throttle_bp

PARAMS = ("A_R", "A_B", "L_R0", "L_C0", "V_B", "KAPPA_PT", "KAPPA_TT", "C_TH", "HA", "T_AMB", "THERMAL", "D_PT",
          "A_BP", "L_BP", "N_BP", "BAND_H", "BAND_L", "M_ROD")
(A_R, A_B, L_R0, L_C0, V_B, KAPPA_PT, KAPPA_TT, C_TH, HA, T_AMB, THERMAL, D_PT, A_BP, L_BP, N_BP, BAND_H, BAND_L,
 M_ROD) = range(len(PARAMS))
STATES = (("P_r", "Pa", 1e5, "rebound chamber pressure"), ("P_c", "Pa", 1e5, "compression chamber pressure"),
          ("P_b", "Pa", 1e5, "third-tube pressure"), ("g_r", "m^3", 1e-7, "entrained gas, rebound"),
          ("g_c", "m^3", 1e-7, "entrained gas, compression"), ("g_b", "m^3", 1e-7, "entrained gas, third tube"),
          ("T_oil", "K", 1.0, "oil temperature"))
PR, PC, PB, GR, GC, GB, T_OIL = range(len(STATES))


@njit(**JIT)
def _floor(P, p, oo):
    return p[oo + P_V] + ramp(P - p[oo + P_V], P_FLOOR_EPS)


@njit(**JIT)
def liquid_volume(P, V0, kappa, g, p, oo):
    """Liquid volume [m^3] of a chamber of rest volume V0 at pressure P."""
    return V0 * (1.0 + kappa * (P - p[oo + P_ATM])) - g * p[oo + P_REF] / _floor(P, p, oo)


@njit(**JIT)
def oil_mass(P, T, V0, kappa, g, p, oo):
    """Oil mass [kg] in a chamber."""
    return density(P, T, p, oo) * liquid_volume(P, V0, kappa, g, p, oo)


@njit(**JIT)
def pressure_rate(P, T, dT, V0, dV0, kappa, g, dg, mdot, p, oo):
    """dP/dt [Pa/s] of a chamber whose rest volume V0 changes at dV0, with
    entrained gas g changing at dg, oil temperature T changing at dT and net
    oil mass inflow mdot [kg/s]: the mass balance solved for dP/dt."""
    Pf = _floor(P, p, oo)
    P_ref = p[oo + P_REF]
    V_l = liquid_volume(P, V0, kappa, g, p, oo)
    compliance = V_l / modulus(P, p, oo) + V0 * kappa + g * P_ref * ramp_slope(P - p[oo + P_V], P_FLOOR_EPS) / (Pf * Pf)
    inflow = (mdot / density(P, T, p, oo) - dV0 * (1.0 + kappa * (P - p[oo + P_ATM])) + P_ref * dg / Pf
              + p[oo + BETA_T] * V_l * dT)
    return inflow / compliance


@njit(**JIT)
def band_leakage(dp, sd, mu, p, o):
    """Piston band clearance rebound -> compression: (flow [m^3/s], shear
    force on the piston [N], tension positive, dissipated power [W]) for
    the pressure difference dp and stroke rate sd (the piston moves towards
    the rebound chamber at sd)."""
    h = p[o + BAND_H]
    if h <= 0.0:
        return 0.0, 0.0, 0.0
    c = math.pi * p[o + D_PT]
    Q = c * (h ** 3 * dp / (12.0 * mu * p[o + BAND_L]) - 0.5 * h * sd)
    F = c * (0.5 * h * dp + mu * p[o + BAND_L] * sd / h)
    return Q, F, dp * Q + F * sd


@njit(**JIT)
def bypass(dp, mu, rho, p, o):
    """Bypass holes rebound -> third tube: N_BP round holes through the
    pressure tube wall (length L_BP), Hagen-Poiseuille + discharge loss."""
    a = p[o + A_BP] / p[o + N_BP]
    r = math.sqrt(a / math.pi)
    R_lam = 8.0 * mu * p[o + L_BP] / (math.pi * r ** 4) / p[o + N_BP]
    return throttle_bp(dp, R_lam, 0.7 * p[o + A_BP], rho)



@njit(**JIT)
def oil_heating(T, P_loss, p, o):
    """dT_oil/dt [K/s]: C_TH dT/dt = P_loss - HA (T - T_amb); 0 when off."""
    if p[o + THERMAL] < 0.5:
        return 0.0
    return (P_loss - p[o + HA] * (T - p[o + T_AMB])) / p[o + C_TH]
