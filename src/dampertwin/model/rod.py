"""Piston rod on the top mount, module configuration (thesis eq. 4.4).

The tube displacement u(t) is prescribed at the lower mount; the rod is a
mass on the top mount, the stroke is s = u - x_rod (THESIS-ERRATA 5).
"""

from __future__ import annotations

from numba import njit

from .declarations import Parameter, State, index_enum
from .top_mount import N_FLD
from .top_mount_backlash import inverse_dead_zone

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
    if q["E_BACKLASH"] > 0.5:  # the rod also crosses the free play
        X = inverse_dead_zone(X, q["TB_DELTA"], q["TB_EPS"])
    return X


STATES = (
    State("x_rod", "m", 1e-4, static_rod_offset, "rod displacement (top-mount deflection)"),
    # scale: the rod's velocity on the top mount reaches 0.1-0.4 m/s in the standard tests; 1e-2 held the
    # error of 1,175 of the 3,272 steps of bench/solver.py at 1e-6 m/s (bench/README.md "State scales")
    State("v_rod", "m/s", 1e-1, 0.0, "rod velocity"),
)
R = index_enum("R", [s.name for s in STATES], __name__)  # offsets inside this submodel's state block


@njit(cache=True, error_model="numpy")
def rod_acceleration(F_d, F_tm, M_rod):
    """Eq. 4.4: M_rod x_rod'' = F_d - F_tm [m/s^2]."""
    return (F_d - F_tm) / M_rod


@njit(cache=True, error_model="numpy", inline="always")
def stroke(y, o, u, du):
    """Stroke s = u - x_rod [m] and its rate [m/s] (THESIS-ERRATA 5)."""
    return u - y[o + R.x_rod], du - y[o + R.v_rod]


@njit(cache=True, error_model="numpy", inline="always")
def rod_position(y, o):
    """Rod displacement and velocity: the top-mount deflection and its rate."""
    return y[o + R.x_rod], y[o + R.v_rod]


@njit(cache=True, error_model="numpy", inline="always")
def motion(y, o, p, F_d, F_tm, dy):
    """Eq. 4.4 in the assembled model; writes dy[o + R.*], returns x_rod''."""
    a = rod_acceleration(F_d, F_tm, p[_L.P.M_ROD])
    dy[o + R.x_rod] = y[o + R.v_rod]
    dy[o + R.v_rod] = a
    return a


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
