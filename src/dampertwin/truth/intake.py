"""Intake (check) valve of the truth: a disc on a coil spring over a seat
of finite width.

The disc (mass M) is held on its seat ring r_in..r_out by a helical spring
of rate K_S with installed preload F_S (Wahl, Mechanical Springs, 1963: a
linear rate over the working deflection). Closed, the pressure acts on the
inner disc and, through the leakage's logarithmic profile, on the land
(fluid.land_area: A_P). Open, the flow passes the holes (A_HOLE) and the
curtain 2 pi r_in h in series, with laminar radial flow over the land
(Merritt 1967 eq. 3-41). The holes lie in series before the disc: its face
carries the pressure after their loss, P_up - rho Q|Q| / (2 (CD A_HOLE)^2),
and their jet's momentum flux rho Q|Q| / A_HOLE pushes it open (Merritt
1967 ch. 5). Seat and stop: Hunt-Crossley contacts.
"""

from __future__ import annotations

import math

from numba import njit

from .fluid import JIT, hunt_crossley, radial_gap_resistance, ramp, throttle

PARAMS = ("A_P", "K_S", "F_S", "M", "C", "R_IN", "R_OUT", "A_HOLE", "CD", "X_MAX", "K_C", "LAM_C", "EPS")
A_P, K_S, F_S, M, C, R_IN, R_OUT, A_HOLE, CD, X_MAX, K_C, LAM_C, EPS = range(len(PARAMS))
STATES = (("x", "m", 1e-4, "disc lift"), ("v", "m/s", 0.1, "disc velocity"))
X, V = range(len(STATES))
GAP_EPS = 2e-7  # [m] rounding of the lift in the flow law


@njit(**JIT)
def intake_valve(y, s, p, o, P_up, P_dn, rho, mu, dy):
    """Writes the disc's state rates; returns (flow [m^3/s], swept area
    [m^2], dissipated power [W])."""
    x = y[s + X]
    v = y[s + V]
    dp = P_up - P_dn
    h = ramp(x, GAP_EPS)
    curtain = p[o + CD] * 2.0 * math.pi * p[o + R_IN] * h
    holes = p[o + CD] * p[o + A_HOLE]
    CdA = curtain * holes / math.sqrt(curtain * curtain + holes * holes + 1e-300)
    Q = throttle(dp, radial_gap_resistance(mu, p[o + R_IN], p[o + R_OUT], h), CdA, rho)
    F_seat, D_seat = hunt_crossley(-x, -v, p[o + K_C], p[o + LAM_C], p[o + EPS])
    F_stop, D_stop = hunt_crossley(x - p[o + X_MAX], v, p[o + K_C], p[o + LAM_C], p[o + EPS])
    F_spring = p[o + F_S] + p[o + K_S] * x
    dp_holes = rho * Q * abs(Q) / (2.0 * holes * holes)  # loss of the holes in series before the face
    F_jet = rho * Q * abs(Q) / p[o + A_HOLE]
    force = p[o + A_P] * (dp - dp_holes) + F_jet + F_seat - F_stop - F_spring - p[o + C] * v
    dy[s + X] = v
    dy[s + V] = force / p[o + M]
    loss = dp * Q + (p[o + A_P] * dp_holes - F_jet) * v + p[o + C] * v * v + D_seat + D_stop
    return Q, p[o + A_P], loss
