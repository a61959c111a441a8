"""Free play (backlash) of the top mount (not in the thesis model; off in the
baseline design).

The rubber is deflected only once the rod has crossed a free play of
+-delta [m]: the bushing (eq. 4.32-4.37) sees the dead-zone deflection
X_e = r(X - delta) - r(-X - delta) (dead-zone backlash model, Nordin &
Gutman, Automatica 38 (2002) 1633-1649, eq. 2), r(u) = (u + sqrt(u^2 +
eps^2)) / 2 the smooth ramp with the named rounding eps [m] (deliberately
smooth: no contact switching, no chattering), and the rate X_e' = X_e'(X) X'.
Out of contact the rubber carries no load: the force of its internal states
(K y + C w', eq. 4.37) reaches the rod times the contact share X_e'(X) in
[0, 1] (1 in contact, ~0 across the play), so the rod does on the mount
exactly the work the rubber's dynamic part receives (F_dyn X_e' dt); the
static curve F_LD(X_e) (~0 across the play) stays ungated, a function of X
alone whose work over a closed cycle is the rubber's. Without that share
the states' relaxation passed up to 27 N through a +-0.3 mm play (10 Hz,
+-1 mm). The rest state is unchanged (the states' force is 0 at rest).
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter

PARAMETERS = (
    Parameter("TB_DELTA", "m", "top_mount_backlash.delta", "half width of the free play"),
    Parameter("TB_EPS", "m", "top_mount_backlash.eps", "rounding of the dead zone"),
    Parameter("E_BACKLASH", "-", "effects.top_mount_backlash", "switch: top-mount free play"),
)


@njit(cache=True, error_model="numpy")
def dead_zone(X, delta, eps):
    """Dead-zone deflection X_e [m] and its slope dX_e/dX [-]."""
    u1 = X - delta
    u2 = -X - delta
    s1 = math.sqrt(u1 * u1 + eps * eps)
    s2 = math.sqrt(u2 * u2 + eps * eps)
    return 0.5 * (u1 + s1) - 0.5 * (u2 + s2), 0.5 * (1.0 + u1 / s1) + 0.5 * (1.0 + u2 / s2)


def inverse_dead_zone(Xe: float, delta: float, eps: float) -> float:
    """X with dead_zone(X) = Xe (Newton; for the rest state) [m]."""
    X = Xe + math.copysign(delta, Xe)
    for _ in range(100):
        f, s = dead_zone.py_func(X, delta, eps)
        step = (f - Xe) / s
        X -= step
        if abs(step) < 1e-16:
            break
    return X


@njit(cache=True, error_model="numpy", inline="always")
def backlash(p, X, Xdot):
    """Deflection and rate [m, m/s] the rubber sees and the contact share
    dX_e/dX [-] (X, Xdot, 1 when off)."""
    if p[_L.P.E_BACKLASH] > 0.5:
        Xe, s = dead_zone(X, p[_L.P.TB_DELTA], p[_L.P.TB_EPS])
        return Xe, s * Xdot, s
    return X, Xdot, 1.0


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
