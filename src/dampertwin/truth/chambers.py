"""Chambers of the truth: mass-conservative pressure rates, wall
compliance, oil heating, and the passages between chambers.

Each chamber holds liquid oil (Murnaghan density, thermal expansion) and
entrained gas g [m^3 at P_ref] (isothermal bubbles, V_gas = g P_ref / P).
The tube walls stretch with the pressure difference ACROSS them (a wall
between two oil chambers takes from one what it gives to the other): the
pressure tube between the rebound / compression chambers inside and the
third tube's chamber outside, compliance W = kappa_PT A_B l per bore length
l; the third tube between its chamber and the reservoir, W_T = kappa_TT V_B,
loaded by P_b - P_W with the reservoir at its rest pressure P_W (the gas
precharge: the reservoir's swings are some 1 % of the third tube's);
kappa from Lame's formula (fluid.lame_compliance). The pressure rates follow
from the oil mass balances d(rho V_liq)/dt = mdot, coupled through the
walls (:func:`walled_rates`; the states are pressures, the mass they imply
is conserved, tests/test_truth_physics.py). The passages: the
bypass holes rebound -> third tube (laminar + turbulent), and the piston
band's clearance with Poiseuille and Couette flow and the shear it puts on
the piston (White, Viscous Fluid Flow, 3rd ed. 2006, 3-2). The oil's lumped
temperature rises with the dissipated power and loses HA (T - T_amb).
"""

from __future__ import annotations

import math

from numba import njit

from .fluid import BETA_T, JIT, P_FLOOR_EPS, P_REF, P_V, density, modulus, ramp, ramp_slope
from .fluid import throttle as throttle_bp

PARAMS = ("A_R", "A_B", "L_R0", "L_C0", "V_B", "KAPPA_PT", "KAPPA_TT", "P_W", "C_TH", "HA", "T_AMB", "THERMAL",
          "D_PT", "A_BP", "L_BP", "N_BP", "BAND_H", "BAND_L", "M_ROD", "BAND_ECC", "ARCH")
(A_R, A_B, L_R0, L_C0, V_B, KAPPA_PT, KAPPA_TT, P_W, C_TH, HA, T_AMB, THERMAL, D_PT, A_BP, L_BP, N_BP, BAND_H, BAND_L,
 M_ROD, BAND_ECC, ARCH) = range(len(PARAMS))  # ARCH: the architecture's code (passive.CODES)
STATES = (("P_r", "Pa", 1e5, "rebound chamber pressure"), ("P_c", "Pa", 1e5, "compression chamber pressure"),
          ("P_b", "Pa", 1e5, "third-tube pressure"), ("g_r", "m^3", 1e-7, "entrained gas, rebound"),
          ("g_c", "m^3", 1e-7, "entrained gas, compression"), ("g_b", "m^3", 1e-7, "entrained gas, third tube"),
          ("T_oil", "K", 1.0, "oil temperature"))
PR, PC, PB, GR, GC, GB, T_OIL = range(len(STATES))


@njit(**JIT)
def _floor(P, p, oo):
    return p[oo + P_V] + ramp(P - p[oo + P_V], P_FLOOR_EPS)


@njit(**JIT)
def liquid_volume(P, V, g, p, oo):
    """Liquid volume [m^3] of a chamber of volume V [m^3] at pressure P."""
    return V - g * p[oo + P_REF] / _floor(P, p, oo)


@njit(**JIT)
def oil_mass(P, T, V, g, p, oo):
    """Oil mass [kg] in a chamber."""
    return density(P, T, p, oo) * liquid_volume(P, V, g, p, oo)


@njit(**JIT)
def balance(P, T, dT, V, dV, g, dg, mdot, p, oo):
    """The chamber's mass balance d(rho V_liq)/dt = mdot written as
    a dP/dt + (wall terms) = b: ``a`` [m^3/Pa] the compliance of its liquid
    and free gas, ``b`` [m^3/s] the volume inflow at fixed pressure (net
    oil mass inflow mdot [kg/s], volume growing at dV [m^3/s] with the
    pressures held, free gas g growing at dg, oil warming at dT)."""
    Pf = _floor(P, p, oo)
    P_ref = p[oo + P_REF]
    V_l = liquid_volume(P, V, g, p, oo)
    a = V_l / modulus(P, p, oo) + g * P_ref * ramp_slope(P - p[oo + P_V], P_FLOOR_EPS) / (Pf * Pf)
    b = mdot / density(P, T, p, oo) - dV + P_ref * dg / Pf + p[oo + BETA_T] * V_l * dT
    return a, b


@njit(**JIT)
def pressure_rate(P, T, dT, V, dV, g, dg, mdot, p, oo):
    """dP/dt [Pa/s] of a rigid chamber (see :func:`balance`)."""
    a, b = balance(P, T, dT, V, dV, g, dg, mdot, p, oo)
    return b / a


@njit(**JIT)
def walled_rates(a_r, b_r, a_c, b_c, a_b, b_b, W_r, W_c, W_t):
    """(dP_r, dP_c, dP_b) [Pa/s] of the rebound and compression chambers and
    the third tube's chamber from their balances (a, b) and the wall
    compliances [m^3/Pa]: V_r grows by W_r (P_r - P_b), V_c by W_c (P_c -
    P_b), V_b loses both and grows by W_t (P_b - P_W) (the reservoir at its
    rest pressure P_W, what V_b gains the reservoir loses). The symmetric system
    (a_r + W_r) dP_r - W_r dP_b = b_r, (a_c + W_c) dP_c - W_c dP_b = b_c,
    (a_b + W_r + W_c + W_t) dP_b - W_r dP_r - W_c dP_c = b_b, eliminated."""
    kr = W_r / (a_r + W_r)
    kc = W_c / (a_c + W_c)
    dP_b = (b_b + kr * b_r + kc * b_c) / (a_b + W_t + W_r * (1.0 - kr) + W_c * (1.0 - kc))
    return (b_r + W_r * dP_b) / (a_r + W_r), (b_c + W_c * dP_b) / (a_c + W_c), dP_b


@njit(**JIT)
def band_leakage(dp, sd, mu, p, o):
    """Piston band clearance rebound -> compression: (flow [m^3/s], force on
    the piston [N], tension positive, dissipated power [W]) for the pressure
    difference dp and stroke rate sd (the piston moves towards the rebound
    chamber at sd).

    Frames: the chambers are sized on the bore (A_R, A_B), so the flow is the
    one through the plane moving with the piston face, and the force is what
    the band adds to P_r A_R - P_c A_B. With the gap profile u(y) = dp/(2 mu L)
    y (h - y) - sd y / h (tube wall y = 0, band y = h; White, Viscous Fluid
    Flow, 3rd ed. 2006, 3-2): flow relative to the piston Q = c (h^3 dp /
    (12 mu L) + h sd / 2) (the piston carries half the ring's oil along, the
    squeezed chamber loses the other half); force = shear on the band, c (h
    dp / 2 + mu L sd / h), minus the ring c h the pressures do not act on as
    piston face, c h dp: c (-h dp / 2 + mu L sd / h). Power dp Q + F sd =
    Poiseuille + Couette dissipation (>= 0).

    Eccentric band (effect ``band_eccentricity``, BAND_ECC = eps > 0: the
    piston off the bore's axis by eps h, the local gap h (1 + eps cos th)):
    the thin-gap Poiseuille flow grows with the circumferential mean of the
    local gap cubed, (1 + 1.5 eps^2) (White, Viscous Fluid Flow, 3rd ed.
    2006, 3-2, eccentric annulus, narrow-gap limit), the Couette flow keeps
    the mean gap, and the viscous drag grows with the mean of 1 / gap,
    1 / sqrt(1 - eps^2) (Sommerfeld's integral; Hamrock, Schmid & Jacobson,
    Fundamentals of Fluid Film Lubrication, 2nd ed. 2004, 12.3). mu is the
    oil's dynamic viscosity at its temperature (Walther, fluid.viscosity)."""
    h = p[o + BAND_H]
    if h <= 0.0:
        return 0.0, 0.0, 0.0
    c = math.pi * p[o + D_PT]
    e = p[o + BAND_ECC]
    if e > 0.0:
        Q = c * (h ** 3 * dp / (12.0 * mu * p[o + BAND_L]) * (1.0 + 1.5 * e * e) + 0.5 * h * sd)
        F = c * (-0.5 * h * dp + mu * p[o + BAND_L] * sd / (h * math.sqrt(1.0 - e * e)))
        return Q, F, dp * Q + F * sd
    Q = c * (h ** 3 * dp / (12.0 * mu * p[o + BAND_L]) + 0.5 * h * sd)
    F = c * (-0.5 * h * dp + mu * p[o + BAND_L] * sd / h)
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
