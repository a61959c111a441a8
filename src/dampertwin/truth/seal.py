"""Rod seal of the truth: a generalised Maxwell-slip element with a
pressure-loaded lip.

N parallel elements (spring K_j, slip force W_j = w_j F_max) give the
pre-sliding hysteresis and the breakaway of a lip seal (Lampaert, Al-Bender
& Swevers, IEEE Trans. Autom. Control 48 (2003) 1883). The lip presses on
the rod with its interference and with the rebound-chamber gauge pressure
on the lip's contact: F_max = F0 + K_PR (P_r - P_atm)+ (Mueller & Nau, Fluid
Sealing Technology, 1998, ch. 9); an oil film adds C_V v.
"""

from __future__ import annotations

from numba import njit

from .fluid import JIT, ramp, slip_rate

N_ELEMENTS = 3
PARAMS = ("F0", "K_PR", "C_V", "K_1", "K_2", "K_3", "W_1", "W_2", "W_3", "P_EPS")
F0, K_PR, C_V, K_1, K_2, K_3, W_1, W_2, W_3, P_EPS = range(len(PARAMS))
STATES = tuple((f"z{j + 1}", "m", 1e-5, f"deflection of seal element {j + 1}") for j in range(N_ELEMENTS))
SLIP_EXPONENT = 3.0


@njit(**JIT)
def seal(y, s, p, o, v, P_gauge, dy):
    """Seal force on the rod [N] (positive opposing a positive stroke rate v)
    and its dissipated power [W]; writes the elements' rates."""
    F_max = p[o + F0] + p[o + K_PR] * ramp(P_gauge, p[o + P_EPS])
    F = p[o + C_V] * v
    loss = p[o + C_V] * v * v
    for j in range(N_ELEMENTS):
        f = p[o + K_1 + j] * y[s + j]
        dz = slip_rate(v, f, p[o + W_1 + j] * F_max, SLIP_EXPONENT)
        dy[s + j] = dz
        F += f
        loss += f * (v - dz)
    return F, loss
