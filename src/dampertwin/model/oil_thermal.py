"""Oil temperature rising with the dissipated power (not in the thesis model,
which holds oil.T constant and takes the oil modulus independent of the
temperature, 4.3 before eq. 4.15; off in the baseline design).

Lumped thermal mass C_th [J/K] (oil, gas and tubes at one temperature T)
heated by the power the damper dissipates and cooled by convection to the
ambient (at the design's oil.T):
C_th dT/dt = F_d s' - hA (T - T_amb)
(lumped thermal damper model: Lion & Loose, Technische Mechanik 22 (2002)
1-11; Calvo et al., Int. J. Vehicle Design 2009). The temperature acts on
- the viscosity, nu = nu0 exp(-b_nu (T - T0)) (Reynolds law; Seeton,
  Tribology Letters 22 (2006) 67-78);
- the OIL's bulk modulus only: the isothermal tangent modulus of mineral oil
  falls linearly, K_oil(T) = K_oil0 (1 - c_K (T - T0)) (Totten, Handbook of
  Hydraulic Fluid Technology, 2000, ch. 3). It enters eq. 4.15 in place of K_oil;
  the wall (eq. 4.17-4.18) and the free gas keep their own laws;
- the emulsion's free gas: eq. 4.15's factor T/T_ref is taken at T (ideal
  gas at fixed pressure);
- the reserve gas: ideal gas, at fixed volume its pressure scales with the
  absolute temperature, P_res = P0 (V0/V_g)^Gamma T/T0 (THESIS-ERRATA 8
  times T/T0);
- the oil's thermal expansion, beta_T [1/K]: at fixed mass the oil of a
  chamber of volume V grows by beta_T V dT, so eq. 4.9 becomes
  Q = dV/dt - beta_T V dT/dt + V/K dP/dt (the expansion feeds the pressure
  rates as a volume source; Merritt, Hydraulic Control Systems, 1967, 2.3).
  The oil in the reserve is left out (the design gives no reserve oil volume).
One state, T_oil [K], in the extended configurations only.
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter, State

PARAMETERS = (
    Parameter("TH_C", "J/K", "oil_thermal.C_th", "lumped heat capacity of oil and tubes"),
    Parameter("TH_HA", "W/K", "oil_thermal.hA", "convective conductance to the ambient"),
    Parameter("TH_BNU", "1/K", "oil_thermal.b_nu", "temperature coefficient of the viscosity"),
    Parameter("TH_CK", "1/K", "oil_thermal.c_K", "relative drop of the oil's bulk modulus per kelvin"),
    Parameter("TH_BETA", "1/K", "oil_thermal.beta_T", "volumetric thermal expansion coefficient of the oil"),
    Parameter("E_THERMAL", "-", "effects.oil_thermal", "switch: oil temperature state"),
)

STATES = (State("T_oil", "K", 1.0, lambda q: q["TEMP"], "oil temperature"),)

K_FACTOR_MIN = 0.2  # floor of the modulus factor (far outside the law's validity)


@njit(cache=True, error_model="numpy")
def viscosity(nu0, b_nu, dT):
    """Kinematic viscosity [m^2/s] at dT [K] above the reference (exponential law)."""
    return nu0 * math.exp(-b_nu * dT)


@njit(cache=True, error_model="numpy")
def modulus_factor(c_K, dT):
    """K_oil(T)/K_oil(T0) = 1 - c_K dT, floored at K_FACTOR_MIN [-]."""
    return max(1.0 - c_K * dT, K_FACTOR_MIN)


@njit(cache=True, error_model="numpy")
def temperature_rate(P_diss, T, T_amb, C_th, hA):
    """dT/dt = (P_diss - hA (T - T_amb)) / C_th [K/s]."""
    return (P_diss - hA * (T - T_amb)) / C_th


@njit(cache=True, error_model="numpy")
def expansion_rate(beta_T, V, dT):
    """Volume growth rate [m^3/s] of the oil filling volume V [m^3] at dT/dt [K/s]."""
    return beta_T * V * dT


@njit(cache=True, error_model="numpy", inline="always")
def expansion(p, V_r, V_c, V_b, dT):
    """Oil volume growth rates [m^3/s] of the rebound, compression and
    third-tube chambers at dT/dt [K/s] (zeros when off)."""
    if p[_L.P.E_THERMAL] > 0.5:
        b = p[_L.P.TH_BETA]
        return expansion_rate(b, V_r, dT), expansion_rate(b, V_c, dT), expansion_rate(b, V_b, dT)
    return 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy", inline="always")
def oil_viscosity(y, o, p):
    """Kinematic viscosity [m^2/s] at the oil temperature y[o] (p[P.NU] when off)."""
    if p[_L.P.E_THERMAL] > 0.5:
        return viscosity(p[_L.P.NU], p[_L.P.TH_BNU], y[o] - p[_L.P.TEMP])
    return p[_L.P.NU]


@njit(cache=True, error_model="numpy", inline="always")
def oil_state(y, o, p):
    """(K_oil [Pa], T [K]) for the chamber moduli: the oil law at y[o] with the
    effect on, else the design's oil.K_oil and oil.T."""
    if p[_L.P.E_THERMAL] > 0.5:
        return p[_L.P.K_OIL] * modulus_factor(p[_L.P.TH_CK], y[o] - p[_L.P.TEMP]), y[o]
    return p[_L.P.K_OIL], p[_L.P.TEMP]


@njit(cache=True, error_model="numpy", inline="always")
def gas_temperature_factor(y, o, p):
    """T/T0 [-] of the reserve gas (ideal gas at fixed volume; 1 when off)."""
    if p[_L.P.E_THERMAL] > 0.5:
        return y[o] / p[_L.P.TEMP]
    return 1.0


@njit(cache=True, error_model="numpy", inline="always")
def oil_temperature(y, o, p):
    """Oil temperature [K]: the state y[o] with the effect on, else the design's oil.T."""
    if p[_L.P.E_THERMAL] > 0.5:
        return y[o]
    return p[_L.P.TEMP]


@njit(cache=True, error_model="numpy", inline="always")
def heat(y, o, p, P_diss, dy):
    """Writes dT/dt at dy[o] for the dissipated power P_diss [W] (0 when off); returns it."""
    if p[_L.P.E_THERMAL] > 0.5:
        dy[o] = temperature_rate(P_diss, y[o], p[_L.P.TEMP], p[_L.P.TH_C], p[_L.P.TH_HA])
    else:
        dy[o] = 0.0
    return dy[o]


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
