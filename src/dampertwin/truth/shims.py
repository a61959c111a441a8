"""Shim-stack valve (piston rebound, base compression) of the truth.

The stack is a set of n1 equal face shims clamped at radius b on a seat at
their outer radius a, bent by the pressure on the ports' face (r1..a) and
by the seat reaction; annular-plate bending (plate.py: Timoshenko &
Woinowsky-Krieger 2.15/2.18, Roark table 11.2 cases 1L/2L) gives its edge
stiffness K1 and pressure-equivalent area A_EQ (also the swept volume per
unit lift, Maxwell-Betti). A preload ring raises the seat by DELTA: the
closed stack presses with K1 DELTA. A backing set of smaller shims (edge
stiffness K2 at radius a2, deflection ratio PSI = w(a2)/w(a)) engages when
the face set has bent through the crossover gap GAP at a2: the stack
stiffens as the shims come to bear on one another (Talbott & Starkey, SAE
2002-01-0245 / Farjoud, Ahmadian, Craft, Zhang, J. Sound Vib. 331 (2012)
1575: shim-stack stiffening and hysteresis). Shim-to-shim friction: one
Maxwell-slip element of stiffness K_MU whose slip force is MU times the
stack's elastic force (Coulomb friction between the sliding faces, normal
load from bending). Flow: the curtain 2 pi a h in series with the ports,
and laminar radial flow over the seat land of width W_S (finite seat
width); a bleed notch in parallel. The ports lie in series before the
stack: the face under it carries the pressure after the ports' loss,
P_face = P_up - rho Q|Q| / (2 (CD A_PORT)^2), and the ports' jet adds its
momentum flux rho Q|Q| / A_PORT (Merritt 1967 ch. 5), so the port head is
not counted twice. Seat and lift stop: Hunt-Crossley contacts. Power
balance: what the chambers lose (the flows' dp Q and the swept volume's
(P_up - P_dn) A_EQ v) is the dissipation plus the stack's mechanical power.
"""

from __future__ import annotations

import math

from numba import njit

from .fluid import JIT, hunt_crossley, radial_gap_resistance, ramp, slip_rate, throttle

PARAMS = ("A_EQ", "K1", "DELTA", "K2", "PSI", "GAP", "MU", "K_MU", "M", "C", "R_S", "W_S", "A_PORT", "CD",
          "X_MAX", "A_BLEED", "L_BLEED", "K_C", "LAM_C", "EPS", "FRICTION")
(A_EQ, K1, DELTA, K2, PSI, GAP, MU, K_MU, M, C, R_S, W_S, A_PORT, CD, X_MAX, A_BLEED, L_BLEED, K_C, LAM_C, EPS,
 FRICTION) = range(len(PARAMS))
STATES = (("x", "m", 1e-4, "edge lift of the face shims"), ("v", "m/s", 0.1, "lift rate"),
          ("z", "m", 1e-6, "shim-to-shim slip element deflection"))
X, V, Z = range(len(STATES))
SLIP_EXPONENT = 4.0  # sharpness of the stick-slip transition (Bouc-Wen n)
GAP_EPS = 2e-7  # [m] rounding of the lift in the flow law (no flow singularity at the seat)


@njit(**JIT)
def elastic_force(x, p, o):
    """Stack force at the seat [N] for edge lift x: face set with preload
    plus the backing set beyond the crossover gap."""
    e = ramp(p[o + PSI] * x - p[o + GAP], p[o + EPS])
    return p[o + K1] * (x + p[o + DELTA]) + p[o + K2] * p[o + PSI] * e


@njit(**JIT)
def shim_valve(y, s, p, o, P_up, P_dn, rho, mu, dy):
    """Writes the stack's state rates; returns (valve flow, bleed flow
    [m^3/s], swept-volume coefficient A_EQ [m^2], dissipated power [W])."""
    x = y[s + X]
    v = y[s + V]
    z = y[s + Z]
    dp = P_up - P_dn
    h = ramp(x, GAP_EPS)
    curtain = p[o + CD] * 2.0 * math.pi * p[o + R_S] * h
    port = p[o + CD] * p[o + A_PORT]
    CdA = 1.0 / math.sqrt(1.0 / (curtain * curtain + 1e-300) + 1.0 / (port * port))
    R_lam = radial_gap_resistance(mu, p[o + R_S] - p[o + W_S], p[o + R_S], h)
    Q = throttle(dp, R_lam, CdA, rho)
    r_b = math.sqrt(p[o + A_BLEED] / math.pi)  # notch as a short round duct (Hagen-Poiseuille laminar part)
    Qb = throttle(dp, 8.0 * mu * p[o + L_BLEED] / (math.pi * r_b ** 4), 0.7 * p[o + A_BLEED], rho)
    F_el = elastic_force(x, p, o)
    F_mu = 0.0
    dz = 0.0
    if p[o + FRICTION] > 0.5:
        F_mu = p[o + K_MU] * z
        dz = slip_rate(v, F_mu, p[o + MU] * abs(F_el) + 1e-3, SLIP_EXPONENT)
    F_seat, D_seat = hunt_crossley(-x, -v, p[o + K_C], p[o + LAM_C], p[o + EPS])
    F_stop, D_stop = hunt_crossley(x - p[o + X_MAX], v, p[o + K_C], p[o + LAM_C], p[o + EPS])
    dp_port = rho * Q * abs(Q) / (2.0 * port * port)  # loss of the ports in series before the face
    F_jet = rho * Q * abs(Q) / p[o + A_PORT]
    force = p[o + A_EQ] * (dp - dp_port) + F_jet + F_seat - F_stop - F_el - F_mu - p[o + C] * v
    dy[s + X] = v
    dy[s + V] = force / p[o + M]
    dy[s + Z] = dz
    loss = (dp * (Q + Qb) + (p[o + A_EQ] * dp_port - F_jet) * v + p[o + C] * v * v + F_mu * (v - dz) + D_seat
            + D_stop)
    return Q, Qb, p[o + A_EQ], loss
