"""Aeration: free air in the compression chamber, released from and
dissolved into the oil at finite rates (thesis 7.3: the shape at the start of
the compression stroke "characteristic of the aeration of the compression
chamber during rebound stroke", from a too-low reserve pressure or an
oil-gas emulsion sucked through the base valve; not in the thesis model,
whose gas content eq. 4.14-4.16 follows the pressure without delay; off in
the baseline design).

State V_a [m^3]: the free air in the compression chamber as its volume at
P_atm (its amount). At pressure P [Pa abs] it fills V_air = V_a (P_atm/P)^(1/n)
(polytropic bubbles, n = 1 isothermal); the oil fills V_oil = V_c - V_air.
Henry's law for the equilibrium, the oil saturated with air at the precharge
P0 (it lies under the reserve's gas) and carrying alpha0 entrained free air
there: V_eq = V_oil ramp(alpha0 + H (P0 - P)/P_atm), H the Bunsen
coefficient (~0.09 for mineral oil; Gholizadeh, Burton & Schoenau,
Int. J. Fluid Power 13 (2012), review of low-pressure bulk modulus models
with entrained air; Totten, Handbook of Hydraulic Fluid Technology, 2000, ch. 6). The air
relaxes to it at finite rates, released faster than dissolved, both far
slower than vapour cavitation (Gholizadeh et al. 2012):
dV_a/dt = (V_eq - V_a) / tau, tau = tau_rel if V_eq > V_a else tau_dis
(continuous at the switch: both branches vanish there).
Volume balance of the chamber (eq. 4.9 with V_c = V_oil + V_air):
V_c/K_eff dP/dt = -(dV_c/dt + Q_out) + (P_atm/P)^(1/n) dV_a/dt,
V_c/K_eff = V_oil/K + V_air/(n P), K the oil / emulsion / wall modulus of
eq. 4.13-4.18 (Wood's mixture law; Duym, Vehicle System Dynamics 33 (2000)
261-285, eq. 12). The bubbles stay in the chamber (not carried by the valve
flows). In the limit tau -> 0 and H = 0 this is the static Boyle law
x = alpha0 (P_atm/P)^(1/n) of free air per oil volume.
"""

from __future__ import annotations

from numba import njit

from .declarations import Parameter, State
from .fluid import P_FLOOR

PARAMETERS = (
    Parameter("AE_ALPHA0", "-", "aeration.alpha0", "entrained free air per oil volume at the precharge (at P_atm)"),
    Parameter("AE_N", "-", "aeration.n", "polytropic exponent of the air"),
    Parameter("AE_H", "-", "aeration.H", "Bunsen coefficient of air in the oil (Henry's law)"),
    Parameter("AE_TREL", "s", "aeration.tau_rel", "time constant of the air's release"),
    Parameter("AE_TDIS", "s", "aeration.tau_dis", "time constant of the air's dissolution"),
    Parameter("E_AERATION", "-", "effects.aeration", "switch: free air in the compression chamber"),
)

ALPHA_EPS = 1e-4  # [-] width of the equilibrium ramp's rounding above full dissolution (C1; 0 below)


def _initial(q):
    """Equilibrium at the precharge and zero stroke: V_a = alpha0 V_oil."""
    if q["E_AERATION"] < 0.5:
        return 0.0
    a, V_c = q["AE_ALPHA0"], q["A_B"] * q["L_C0"]
    return a * V_c / (1.0 + a * (q["P_ATM"] / q["P0"]) ** (1.0 / q["AE_N"]))


STATES = (State("V_air", "m^3", 1e-6, _initial, "free air in the compression chamber (volume at P_atm)"),)


@njit(cache=True, error_model="numpy")
def ramp(u, eps):
    """max(u, 0) with its corner rounded on 0 < u < eps by the cubic
    (u^2 / eps)(2 - u / eps) (C1: value and slope match at 0 and eps):
    exactly 0 for u <= 0, so alpha0 = H = 0 is the model without air, and
    exactly u for u >= eps, so the precharge state alpha0 >= eps is an
    equilibrium."""
    if u >= eps:
        return u
    if u <= 0.0:
        return 0.0
    return u * u / eps * (2.0 - u / eps)


@njit(cache=True, error_model="numpy")
def free_air(V_a, P, P_atm, n):
    """Volume [m^3] the free air of amount V_a (volume at P_atm) fills at P [Pa abs]."""
    return V_a * (P_atm / max(P, P_FLOOR)) ** (1.0 / n)


@njit(cache=True, error_model="numpy")
def equilibrium_content(P, P0, P_atm, alpha0, H):
    """Henry equilibrium of the free air per oil volume (at P_atm) at P [-]."""
    return ramp(alpha0 + H * (P0 - P) / P_atm, ALPHA_EPS)


@njit(cache=True, error_model="numpy")
def air_rate(V_a, V_eq, tau_rel, tau_dis):
    """dV_a/dt [m^3/s]: release (V_eq > V_a) or dissolution at finite rates."""
    d = V_eq - V_a
    return d / tau_rel if d > 0.0 else d / tau_dis


@njit(cache=True, error_model="numpy")
def aerated_chamber(K, P, V_c, V_a, P0, P_atm, alpha0, n, H, tau_rel, tau_dis):
    """Effective modulus K_eff [Pa] of the compression chamber (volume V_c,
    oil modulus K) with free air V_a, the volume source (P_atm/P)^(1/n) dV_a/dt
    [m^3/s] the released air adds, and dV_a/dt."""
    Pf = max(P, P_FLOOR)
    r = (P_atm / Pf) ** (1.0 / n)
    V_air = V_a * r
    V_oil = V_c - V_air
    K_eff = V_c / (V_oil / K + V_air / (n * Pf))
    dV_a = air_rate(V_a, V_oil * equilibrium_content(P, P0, P_atm, alpha0, H), tau_rel, tau_dis)
    return K_eff, r * dV_a, dV_a


@njit(cache=True, error_model="numpy", inline="always")
def aeration(y, o, p, K_c, P_c, V_c, dy):
    """The compression chamber's modulus [Pa] and the released air's volume
    source [m^3/s] with the free air y[o]; writes dV_a/dt at dy[o]
    (K_c, 0 and no rate when off)."""
    if p[_L.P.E_AERATION] > 0.5:
        K, src, dy[o] = aerated_chamber(K_c, P_c, V_c, y[o], p[_L.P.P0], p[_L.P.P_ATM], p[_L.P.AE_ALPHA0],
                                        p[_L.P.AE_N], p[_L.P.AE_H], p[_L.P.AE_TREL], p[_L.P.AE_TDIS])
        return K, src
    dy[o] = 0.0
    return K_c, 0.0


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
