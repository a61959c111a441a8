"""Top mount: AutoBushFD-like rubber bushing (thesis 4.5, eq. 4.32-4.37).

X is the bushing deflection [m] (rod displacement relative to the housing),
x its high-passed copy, y and w internal states [m]. Power terms use
y_unit = 1 mm and w_unit = 1 mm/s (THESIS-ERRATA 32). Requires c1 > 0
(THESIS-ERRATA 33).
"""

from __future__ import annotations

from numba import njit

from .declarations import Parameter, State, index_enum
from .numerics import power
from .top_mount_backlash import backlash

N_FLD = 5  # coefficients of the static load-deflection polynomial


def _fld(k):
    def get(d):
        coef = d["top_mount.F_LD"]
        if len(coef) > N_FLD:
            raise ValueError(f"design {d.name!r}: top_mount.F_LD has {len(coef)} coefficients; at most {N_FLD} supported")
        return coef[k] if k < len(coef) else 0.0
    return get


PARAMETERS = (
    Parameter("TM_R", "1/s", "top_mount.R", "high-pass rate of x, eq. 4.32"),
    *(Parameter(f"TM_{n.upper()}", u, f"top_mount.{n}", f"AutoBushFD parameter {n}, eq. 4.33-4.36")
      for n, u in (("p0", "-"), ("p1", "-"), ("p2", "-"), ("q0", "-"), ("q1", "-"), ("q2", "-"),
                   ("k0", "N/m"), ("k1", "N/m"), ("k2", "N/m"), ("c0", "N s/m"), ("c1", "N s/m"), ("c2", "N s/m"))),
    Parameter("TM_YU", "m", "constants.y_unit", "unit of y in the power terms (errata 32)"),
    Parameter("TM_WU", "m/s", "constants.w_unit", "unit of w' in the power terms (errata 32)"),
    *(Parameter(f"TM_FLD{k}", f"N/m^{k + 1}", _fld(k), f"F_LD coefficient of X^{k + 1}") for k in range(N_FLD)),
    Parameter("E_TM_DYNAMICS", "-", "effects.top_mount_dynamics", "switch: rubber dynamics (else static curve)"),
)

STATES = (
    State("tm_x", "m", 1e-4, 0.0, "high-passed deflection, eq. 4.32"),
    State("tm_y", "m", 1e-4, 0.0, "elastic internal state, eq. 4.33"),
    State("tm_w", "m", 1e-4, 0.0, "damping internal state, eq. 4.34"),
)
TM = index_enum("TM", [s.name for s in STATES], __name__)  # offsets inside this submodel's state block


@njit(cache=True, error_model="numpy", inline="always")
def static_force(X, coef, o, n):
    """Static load-deflection polynomial F_LD(X) = sum_k coef[o + k-1] X^k, k = 1..n [N]
    (the coefficients read in place: a slice would cost a reference count per call)."""
    f = 0.0
    xp = X
    for k in range(n):
        f += coef[o + k] * xp
        xp *= X
    return f


@njit(cache=True, error_model="numpy")
def top_mount_rates(Xdot, x, y, w, R, k0, k1, k2, c0, c1, c2):
    """State rates of eq. 4.32-4.34. Returns (x', y', w')."""
    xd = Xdot - R * x  # eq. 4.32
    yd = (c1 * xd + k1 * (x - y) - k0 * y) / c1  # eq. 4.33
    wd = (c2 * xd + k2 * (x - w)) / (c0 + c2)  # eq. 4.34
    return xd, yd, wd


@njit(cache=True, error_model="numpy", inline="always")
def top_mount_force(X, y, wd, p0, p1, p2, q0, q1, q2, k0, c0, y_unit, w_unit, coef, o, dynamics, contact):
    """Bushing force eq. 4.35-4.37, F = contact (K y + C w') + F_LD(X) [N]
    (F_LD's coefficients at coef[o:o + N_FLD]); with ``dynamics`` false only
    the static curve. ``contact`` [-] is 1 but across a free play
    (top_mount_backlash), where the rubber, out of contact, passes on none
    of its internal states' force."""
    F = static_force(X, coef, o, N_FLD)
    if dynamics:
        K = k0 * (p0 + p1 * power(abs(y / y_unit), p2))  # eq. 4.35
        C = c0 * (q0 + q1 * power(abs(wd / w_unit), q2))  # eq. 4.36
        F += contact * (K * y + C * wd)  # eq. 4.37
    return F


@njit(cache=True, error_model="numpy", inline="always")
def mount(y, o, p, X, Xdot, dy):
    """The top-mount submodel in the assembled model: force [N] at deflection
    X [m] and rate Xdot [m/s]; writes its state rates into dy[o + TM.*]
    (frozen when the dynamics are switched off). With top_mount_backlash
    the rubber sees the dead-zone deflection."""
    X, Xdot, contact = backlash(p, X, Xdot)
    x = y[o + TM.tm_x]
    yy = y[o + TM.tm_y]
    w = y[o + TM.tm_w]
    xd, yd, wd = top_mount_rates(Xdot, x, yy, w, p[_L.P.TM_R], p[_L.P.TM_K0], p[_L.P.TM_K1], p[_L.P.TM_K2],
                                 p[_L.P.TM_C0], p[_L.P.TM_C1], p[_L.P.TM_C2])
    dyn = p[_L.P.E_TM_DYNAMICS] > 0.5
    F = top_mount_force(X, yy, wd, p[_L.P.TM_P0], p[_L.P.TM_P1], p[_L.P.TM_P2], p[_L.P.TM_Q0], p[_L.P.TM_Q1],
                        p[_L.P.TM_Q2], p[_L.P.TM_K0], p[_L.P.TM_C0], p[_L.P.TM_YU], p[_L.P.TM_WU],
                        p, _L.P.TM_FLD0, dyn, contact)
    dy[o + TM.tm_x] = xd if dyn else 0.0
    dy[o + TM.tm_y] = yd if dyn else 0.0
    dy[o + TM.tm_w] = wd if dyn else 0.0
    return F


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
