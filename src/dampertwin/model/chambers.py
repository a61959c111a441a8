"""Chambers and rod force (thesis 4.1-4.2, eq. 4.1-4.12).

Sign convention (THESIS-ERRATA 3): stroke s > 0 is extension (rebound): the
rebound volume shrinks, the compression volume grows. Pressures absolute.
"""

from __future__ import annotations

import math

from numba import njit

# Cavitation: the effective modulus fades to CAV_MIN of its value as the
# pressure falls to the vapour pressure over CAV_BAND, and decays
# exponentially (rate CAV_DECAY per band) below it, so a chamber is not pulled
# below P_vap (a vapour cavity forms instead) yet always recovers.
CAV_BAND = 0.3e5  # [Pa]
CAV_MIN = 1e-3
CAV_DECAY = 5.0


@njit(cache=True)
def chamber_volumes(s, A_r, A_b, l_r0, l_c0):
    """Rebound and compression volumes, eq. 4.5-4.6 (A_c read as A_b, errata 4)."""
    return A_r * (l_r0 - s), A_b * (l_c0 + s)


@njit(cache=True)
def cavitation_factor(P, P_vap):
    """Smooth factor in [CAV_MIN, 1] scaling the modulus near P_vap."""
    u = (P - P_vap) / CAV_BAND
    if u >= 1.0:
        return 1.0
    if u <= 0.0:
        return CAV_MIN * math.exp(CAV_DECAY * u)
    return CAV_MIN + (1.0 - CAV_MIN) * u * u * (3.0 - 2.0 * u)


@njit(cache=True)
def pressure_rate(K, V, dV, Q_out):
    """dP/dt = -K/V (dV/dt + Q_out), eq. 4.9-4.12, Q_out the net outflow."""
    return -K / V * (dV + Q_out)


@njit(cache=True)
def rod_force(P_r, P_c, A_r, A_b, P_atm, F_mu):
    """Force on the rod, eq. 4.1 from a free-body diagram (THESIS-ERRATA 1, 2):
    (P_r - P_atm) A_r - (P_c - P_atm) A_b + F_mu, A_r the annulus. Positive
    = tension (rebound) [N]."""
    return (P_r - P_atm) * A_r - (P_c - P_atm) * A_b + F_mu
