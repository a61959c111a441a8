"""Gas release and dissolution at finite rates: the undissolved share theta of
the emulsion's gas (thesis eq. 4.14) as a state per chamber instead of its
equilibrium (thesis 7.3 names aeration and the gas's behaviour at low
pressure; not in the thesis model, where theta follows the pressure without
delay; off in the baseline design).

Eq. 4.14 is Henry's equilibrium theta_eq(P) (the REG-1 blended clip of
fluid.gas_fraction). Gas leaves solution and redissolves at finite rates,
release faster than dissolution, both far slower than vapour cavitation
(Gholizadeh, Burton & Schoenau, Int. J. Fluid Power 13 (2012) 7, review;
Zhou, Vacca & Manhartsgruber, J. Fluids Eng. 135 (2013) 091305: first-order
release / absorption with separate time constants):

    dtheta/dt = (theta_eq(P) - theta) / tau,  tau = tau_rel if theta_eq > theta else tau_dis

(continuous at the switch: both branches vanish there). The emulsion's
density eq. 4.15 is rho = rho_mix / D(P, theta), D = (1 - chi) exp(-(P -
P_ref)/K_oil) + theta chi T/T_ref (P_ref/P)^(1/Gamma). The mass balance of a
chamber, V drho/dt = -rho (dV/dt + Q_out), with D_P = dD/dP at fixed theta
and D_theta = dD/dtheta, gives

    dP/dt = -K_f/V (dV/dt + Q_out - S),  K_f = -D / D_P,  S = V D_theta dtheta/dt / D:

the frozen modulus K_f (eq. 4.16 without its dissolution term, THESIS-ERRATA
11: stiffer) and the released gas as a volume source S. K_f takes the
wall in series and the cavitation factor as eq. 4.13 (chambers.structure).
tau -> 0 gives theta = theta_eq(P) and the thesis' modulus K = -D /
(D_P + D_theta theta_eq'): the model without the effect.

Not the ``aeration`` effect: that one ADDS an amount of free air (alpha0, a
Henry law of its own) to the compression chamber, so even static it softens
that chamber; this one adds no gas (the calibrated oil.chi, P_sat, P_vap
keep their meaning and their static law) and only delays the existing gas
in all three chambers: stiffer in fast cycles, with a memory of low-pressure
phases. With chi = 0 it does nothing (with gas_content off a design is refused:
schema.EFFECT_NEEDS). Three states, in
the extended configurations only (layout.variant).
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter, State
from .fluid import P_FLOOR, gas_fraction

PARAMETERS = (
    Parameter("GR_TREL", "s", "gas_release.tau_rel", "time constant of the gas's release (eq. 4.14 share)"),
    Parameter("GR_TDIS", "s", "gas_release.tau_dis", "time constant of the gas's dissolution"),
    Parameter("E_GAS_RELEASE", "-", "effects.gas_release", "switch: undissolved gas share as states"),
)


def _rest_share(q):
    """Eq. 4.14 at the precharge (every chamber at P0 at rest)."""
    return float(gas_fraction(q["P0"], q["P_SAT"], q["P_VAP"])[0])


STATES = tuple(State(f"theta_{c}", "-", 0.1, _rest_share, f"undissolved gas share, {name} chamber (eq. 4.14)")
               for c, name in (("r", "rebound"), ("c", "compression"), ("b", "third-tube")))


@njit(cache=True, error_model="numpy")
def share_rate(theta, theta_eq, tau_rel, tau_dis):
    """dtheta/dt [1/s]: release (theta_eq > theta) or dissolution at finite rates."""
    d = theta_eq - theta
    return d / tau_rel if d > 0.0 else d / tau_dis


@njit(cache=True, error_model="numpy")
def frozen_emulsion(P, theta, K_oil, chi, P_ref, T, T_ref, Gamma):
    """(D, K_f [Pa], D_theta / D [-]) of eq. 4.15 at pressure P [Pa abs] with
    the undissolved share theta held: K_f = -D / (dD/dP at fixed theta)."""
    P = max(P, P_FLOOR)
    e = math.exp(-(P - P_ref) / K_oil)
    g = (P_ref / P) ** (1.0 / Gamma)
    tt = chi * T / T_ref
    D = (1.0 - chi) * e + theta * tt * g
    D_P = -(1.0 - chi) * e / K_oil - theta * tt * g / (Gamma * P)
    return D, -D / D_P, tt * g / D


@njit(cache=True, error_model="numpy")
def released_chamber(P, theta, V, K_oil, chi, P_sat, P_vap, P_ref, T, T_ref, Gamma, tau_rel, tau_dis):
    """(frozen fluid modulus K_f [Pa], volume source S [m^3/s], dtheta/dt [1/s])
    of a chamber of volume V [m^3] at P [Pa abs] with the gas share theta."""
    th_eq = gas_fraction(max(P, P_FLOOR), P_sat, P_vap)[0]
    dth = share_rate(theta, th_eq, tau_rel, tau_dis)
    _, K_f, d_theta = frozen_emulsion(P, theta, K_oil, chi, P_ref, T, T_ref, Gamma)
    return K_f, V * d_theta * dth, dth


@njit(cache=True, error_model="numpy", inline="always")
def gas_release(y, o, p, K_r, K_c, K_b, P_r, P_c, P_b, P_res, K_oil, T, V_r, V_c, dy):
    """The three chambers' moduli [Pa] and released-gas volume sources [m^3/s]
    with the gas shares y[o], y[o + 1], y[o + 2] (rebound, compression, third
    tube; rates written); the moduli K_r, K_c, K_b given and no source when off."""
    if p[_L.P.E_GAS_RELEASE] > 0.5 and p[_L.P.E_GAS] > 0.5 and p[_L.P.CHI] > 0.0:
        a = (K_oil, p[_L.P.CHI], p[_L.P.P_SAT], p[_L.P.P_VAP], p[_L.P.P_REF], T, p[_L.P.T_REF], p[_L.P.GAMMA],
             p[_L.P.GR_TREL], p[_L.P.GR_TDIS])
        Kf_r, S_r, dy[o] = released_chamber(P_r, y[o], V_r, *a)
        Kf_c, S_c, dy[o + 1] = released_chamber(P_c, y[o + 1], V_c, *a)
        Kf_b, S_b, dy[o + 2] = released_chamber(P_b, y[o + 2], p[_L.P.V_B], *a)
        K_r, K_c, K_b = structure(p, Kf_r, Kf_c, Kf_b, P_r, P_c, P_b, P_res)
        return K_r, K_c, K_b, S_r, S_c, S_b
    dy[o] = 0.0
    dy[o + 1] = 0.0
    dy[o + 2] = 0.0
    return K_r, K_c, K_b, 0.0, 0.0, 0.0


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
from .chambers import structure  # noqa: E402
