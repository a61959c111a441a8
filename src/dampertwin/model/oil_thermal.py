"""Oil temperature rising with the dissipated power (not in the thesis model,
which holds oil.T constant; off in the baseline design).

Lumped thermal mass C_th [J/K] heated by the power the damper dissipates and
cooled by convection to the ambient (at the design's oil.T):
C_th dT/dt = F_d s' - hA (T - T_amb)
(lumped thermal damper model: Lion & Loose, Technische Mechanik 22 (2002)
1-11; Calvo et al., Int. J. Vehicle Design 2009). The viscosity follows the
exponential (Reynolds) law nu = nu0 exp(-b_nu (T - T0)) (Seeton, Tribology
Letters 22 (2006) 67-78), the oil bulk modulus drops linearly,
K = K0 (1 - c_K (T - T0)) (Totten, Handbook of Hydraulic Fluid Technology,
2000, ch. 3). One state, T_oil [K], in the extended configurations only.
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter, State

PARAMETERS = (
    Parameter("TH_C", "J/K", "oil_thermal.C_th", "lumped heat capacity of oil and tubes"),
    Parameter("TH_HA", "W/K", "oil_thermal.hA", "convective conductance to the ambient"),
    Parameter("TH_BNU", "1/K", "oil_thermal.b_nu", "temperature coefficient of the viscosity"),
    Parameter("TH_CK", "1/K", "oil_thermal.c_K", "relative drop of the bulk modulus per kelvin"),
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
    """K(T)/K(T0) = 1 - c_K dT, floored at K_FACTOR_MIN [-]."""
    return max(1.0 - c_K * dT, K_FACTOR_MIN)


@njit(cache=True, error_model="numpy")
def temperature_rate(P_diss, T, T_amb, C_th, hA):
    """dT/dt = (P_diss - hA (T - T_amb)) / C_th [K/s]."""
    return (P_diss - hA * (T - T_amb)) / C_th


@njit(cache=True, error_model="numpy", inline="always")
def oil_viscosity(y, o, p):
    """Kinematic viscosity [m^2/s] at the oil temperature y[o] (p[P.NU] when off)."""
    if p[_L.P.E_THERMAL] > 0.5:
        return viscosity(p[_L.P.NU], p[_L.P.TH_BNU], y[o] - p[_L.P.TEMP])
    return p[_L.P.NU]


@njit(cache=True, error_model="numpy", inline="always")
def thermal_moduli(y, o, p, K_r, K_c, K_b):
    """The chamber moduli [Pa] at the oil temperature y[o] (unchanged when off)."""
    if p[_L.P.E_THERMAL] > 0.5:
        f = modulus_factor(p[_L.P.TH_CK], y[o] - p[_L.P.TEMP])
        return K_r * f, K_c * f, K_b * f
    return K_r, K_c, K_b


@njit(cache=True, error_model="numpy", inline="always")
def oil_temperature(y, o, p):
    """Oil temperature [K]: the state y[o] with the effect on, else the design's oil.T."""
    if p[_L.P.E_THERMAL] > 0.5:
        return y[o]
    return p[_L.P.TEMP]


@njit(cache=True, error_model="numpy", inline="always")
def heat(y, o, p, P_diss, dy):
    """Writes dT/dt at dy[o] for the dissipated power P_diss [W] (0 when off)."""
    if p[_L.P.E_THERMAL] > 0.5:
        dy[o] = temperature_rate(P_diss, y[o], p[_L.P.TEMP], p[_L.P.TH_C], p[_L.P.TH_HA])
    else:
        dy[o] = 0.0


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
