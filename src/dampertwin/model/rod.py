"""Piston rod on the top mount, module configuration (thesis eq. 4.4).

The tube displacement u(t) is prescribed at the lower mount; the rod is a
mass on the top mount, the stroke is s = u - x_rod (THESIS-ERRATA 5).
"""

from __future__ import annotations

from numba import njit

from .declarations import Parameter, State
from .top_mount import N_FLD

PARAMETERS = (Parameter("M_ROD", "kg", "geometry.M_rod", "rod + piston mass (and the sprung share it carries)"),)


def static_rod_offset(q) -> float:
    """Top-mount deflection [m] balancing the static gas force on the rod:
    F_LD(X) = (P0 - P_atm)(A_r - A_b) (THESIS-ERRATA 5)."""
    F0 = (q["P0"] - q["P_ATM"]) * (q["A_R"] - q["A_B"])
    coef = [q[f"TM_FLD{k}"] for k in range(N_FLD)]
    X = F0 / coef[0]
    for _ in range(60):
        F = sum(coef[k] * X ** (k + 1) for k in range(N_FLD))
        dF = sum((k + 1) * coef[k] * X**k for k in range(N_FLD))
        step = (F - F0) / dF
        X -= step
        if abs(step) < 1e-15:
            break
    return X


STATES = (
    State("x_rod", "m", 1e-4, static_rod_offset, "rod displacement (top-mount deflection)"),
    State("v_rod", "m/s", 1e-2, 0.0, "rod velocity"),
)


@njit(cache=True, error_model="numpy")
def rod_acceleration(F_d, F_tm, M_rod):
    """Eq. 4.4: M_rod x_rod'' = F_d - F_tm [m/s^2]."""
    return (F_d - F_tm) / M_rod
