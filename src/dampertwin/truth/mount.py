"""Top mount of the truth: a generalised Maxwell rubber with the Payne
effect.

Elastic backbone K_E X + K_E3 X^3 and three Maxwell branches (spring K_j,
dashpot C_j): relaxation times C_j/K_j spread over decades as a filled
rubber's (Austrell, PhD thesis, Lund 1997; Kari, Polymer Testing 20 (2001)
453 for bushings). The branches' stiffness falls with the strain amplitude
a (Payne effect) by the Kraus law phi = PHI_INF + (1 - PHI_INF) / (1 +
(a / A_C)^(2 M_K)) (Kraus, J. Appl. Polym. Sci. Appl. Polym. Symp. 39
(1984) 75). The amplitude is tracked as sqrt(2 r), r the mean square of
the deflection about its slow mean (time constants TAU_R, TAU_M).
"""

from __future__ import annotations

import math

from numba import njit

from .fluid import JIT

N_BRANCHES = 3
PARAMS = ("K_E", "K_E3", "K_1", "K_2", "K_3", "C_1", "C_2", "C_3", "PHI_INF", "A_C", "M_K", "TAU_R", "TAU_M",
          "PAYNE")
K_E, K_E3, K_1, K_2, K_3, C_1, C_2, C_3, PHI_INF, A_C, M_K, TAU_R, TAU_M, PAYNE = range(len(PARAMS))
STATES = (*((f"y{j + 1}", "m", 1e-4, f"spring deflection of branch {j + 1}") for j in range(N_BRANCHES)),
          ("x_mean", "m", 1e-4, "slow mean of the deflection"), ("r", "m^2", 1e-8, "mean square deflection"))
Y1, Y2, Y3, X_MEAN, MS = range(len(STATES))


@njit(**JIT)
def payne_factor(a, p, o):
    """Kraus factor of the branches' stiffness at amplitude a [m]."""
    if p[o + PAYNE] < 0.5:
        return 1.0
    return p[o + PHI_INF] + (1.0 - p[o + PHI_INF]) / (1.0 + (a / p[o + A_C]) ** (2.0 * p[o + M_K]))


@njit(**JIT)
def mount(y, s, p, o, X, Xd, dy):
    """Mount force [N] at deflection X [m] and rate Xd; writes its states'
    rates; returns (force, dissipated power [W])."""
    d = X - y[s + X_MEAN]
    dy[s + X_MEAN] = d / p[o + TAU_M]
    dy[s + MS] = (d * d - y[s + MS]) / p[o + TAU_R]
    phi = payne_factor(math.sqrt(2.0 * abs(y[s + MS])), p, o)
    F = p[o + K_E] * X + p[o + K_E3] * X * X * X
    loss = 0.0
    for j in range(N_BRANCHES):
        f = phi * p[o + K_1 + j] * y[s + j]
        dy[s + j] = Xd - f / p[o + C_1 + j]
        F += f
        loss += f * f / p[o + C_1 + j]
    return F, loss


def static_deflection(F: float, k: float, k3: float) -> float:
    """Deflection [m] of the backbone under a static force F [N] (Newton)."""
    X = F / k
    for _ in range(50):
        X -= (k * X + k3 * X ** 3 - F) / (k + 3 * k3 * X * X)
    return X
