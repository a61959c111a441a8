"""Top mount of the truth: a generalised Maxwell rubber with the Payne
effect.

Elastic backbone K_E X + K_E3 X^3 and three Maxwell branches (spring K_j,
dashpot C_j): relaxation times C_j/K_j spread over decades as a filled
rubber's (Austrell, PhD thesis, Lund 1997; Kari, Polymer Testing 20 (2001)
453 for bushings). The branches' stiffness falls with the strain amplitude
a (Payne effect) by the Kraus law phi = PHI_INF + (1 - PHI_INF) / (1 +
(a / A_C)^(2 M_K)) (Kraus, J. Appl. Polym. Sci. Appl. Polym. Symp. 39
(1984) 75). The amplitude is tracked as sqrt(2 r), r the mean square of
the deflection about its slow mean (time constants TAU_R, TAU_M). A branch
stores phi K_j y_j^2 / 2; when phi changes, the branch's deflection gives
up the share phi' / (2 phi) y_j per second, so a stiffness change neither
creates nor destroys energy: the power in is the stored energy's rate plus
the dashpots' f^2 / C_j >= 0 (passive; tests/test_truth_physics.py).
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


MS_EPS = 1e-12  # [m^2] floor of the mean square (1 um amplitude): phi'(r) stays finite at rest


@njit(**JIT)
def payne_factor(r, p, o):
    """Kraus factor of the branches' stiffness at mean square deflection r
    [m^2] (amplitude sqrt(2 r)) and its derivative d phi / d r [1/m^2]."""
    if p[o + PAYNE] < 0.5:
        return 1.0, 0.0
    q = (2.0 * (abs(r) + MS_EPS) / p[o + A_C] ** 2) ** p[o + M_K]
    phi = p[o + PHI_INF] + (1.0 - p[o + PHI_INF]) / (1.0 + q)
    dphi = -(1.0 - p[o + PHI_INF]) * p[o + M_K] * q / ((abs(r) + MS_EPS) * (1.0 + q) ** 2)
    return phi, dphi


@njit(**JIT)
def mount(y, s, p, o, X, Xd, dy):
    """Mount force [N] at deflection X [m] and rate Xd; writes its states'
    rates; returns (force, dissipated power [W])."""
    d = X - y[s + X_MEAN]
    dy[s + X_MEAN] = d / p[o + TAU_M]
    dr = (d * d - y[s + MS]) / p[o + TAU_R]
    dy[s + MS] = dr
    phi, dphi = payne_factor(y[s + MS], p, o)
    give_up = 0.5 * dphi * dr / phi  # [1/s]: the energy-neutral share of a stiffness change
    F = p[o + K_E] * X + p[o + K_E3] * X * X * X
    loss = 0.0
    for j in range(N_BRANCHES):
        f = phi * p[o + K_1 + j] * y[s + j]
        dy[s + j] = Xd - f / p[o + C_1 + j] - give_up * y[s + j]
        F += f
        loss += f * f / p[o + C_1 + j]
    return F, loss


def static_deflection(F: float, k: float, k3: float) -> float:
    """Deflection [m] of the backbone under a static force F [N] (Newton)."""
    X = F / k
    for _ in range(50):
        X -= (k * X + k3 * X ** 3 - F) / (k + 3 * k3 * X * X)
    return X
