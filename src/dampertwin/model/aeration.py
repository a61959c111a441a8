"""Aeration: free air entrained in the compression chamber (thesis 7.4; not
in the thesis model, whose gas content eq. 4.14-4.16 is dissolved gas coming
out of solution; off in the baseline design).

Free air of volume alpha0 per oil volume at atmospheric pressure follows the
polytropic (Boyle for n = 1) law, x(P) = alpha0 (P_atm / P)^(1/n); its share
of the mixture is phi = x / (1 + x), and the mixture compliance is that of
oil and air in parallel volumes (Wood's mixture law, the aeration model of
Duym, Vehicle System Dynamics 33 (2000) 261-285, eq. 12):
1/K_eff = (1 - phi)/K + phi/(n P)  [Pa], P absolute.
"""

from __future__ import annotations

from numba import njit

from .declarations import Parameter
from .fluid import P_FLOOR

PARAMETERS = (
    Parameter("AE_ALPHA0", "-", "aeration.alpha0", "free air per oil volume at P_atm"),
    Parameter("AE_N", "-", "aeration.n", "polytropic exponent of the air"),
    Parameter("E_AERATION", "-", "effects.aeration", "switch: free air in the compression chamber"),
)


@njit(cache=True, error_model="numpy")
def aerated_modulus(K, P, P_atm, alpha0, n):
    """Modulus [Pa] of oil (modulus K) with free air alpha0 at pressure P [Pa abs]."""
    P = max(P, P_FLOOR)
    x = alpha0 * (P_atm / P) ** (1.0 / n)
    phi = x / (1.0 + x)
    return 1.0 / ((1.0 - phi) / K + phi / (n * P))


@njit(cache=True, error_model="numpy", inline="always")
def aeration(p, K_c, P_c):
    """The compression chamber's modulus [Pa] with the entrained air (K_c when off)."""
    if p[_L.P.E_AERATION] > 0.5:
        return aerated_modulus(K_c, P_c, p[_L.P.P_ATM], p[_L.P.AE_ALPHA0], p[_L.P.AE_N])
    return K_c


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
