"""Passive valves (thesis 4.4, eq. 4.19-4.31): 1-DOF mass-spring-damper
discs over a seat, with orifice flow through the opening, bleed and slot.

Four valves: piston rebound shim, piston intake, base compression shim, base
intake. Each is described by one block of the parameter vector (layout
``V_*`` below). Lift x [m] positive opening; p1 upstream, p2 downstream [Pa];
flow Q [m^3/s] positive from p1 to p2.
"""

from __future__ import annotations

import math

from numba import njit

# ---- valve parameter block layout (offsets inside a valve's block)
V_DD, V_DI, V_DH, V_CQ, V_LAM, V_AB, V_CQB, V_AS, V_CQS = 0, 1, 2, 3, 4, 5, 6, 7, 8
V_M, V_C, V_SIG, V_FC, V_ALPHA, V_PRE, V_A, V_B, V_CC, V_D = 9, 10, 11, 12, 13, 14, 15, 16, 17, 18
V_XV0, V_XMAX, V_SHIM = 19, 20, 21
V_SIZE = 22


@njit(cache=True)
def regularised_sqrt(dp, p_tr):
    """sign(dp) sqrt|dp| for |dp| >> p_tr, linear (laminar) below the
    transition pressure p_tr: dp / (dp^2 + p_tr^2)^(1/4) (THESIS-ERRATA 26).
    Odd, smooth and monotone."""
    return dp / (dp * dp + p_tr * p_tr) ** 0.25


@njit(cache=True)
def orifice_flow(G, dp, rho, p_tr):
    """Orifice law eq. 4.29, Q = G sqrt(2 dp / rho), with G = Cq A [m^2]."""
    return G * math.sqrt(2.0 / rho) * regularised_sqrt(dp, p_tr)


@njit(cache=True)
def discharge_coefficient(cq_max, lam_crit, x, nu, dp, rho):
    """Cq(lambda), eq. 4.30-4.31, with D_hyd = 2x for the slit
    (THESIS-ERRATA 24), so Cq -> 0 as the valve closes."""
    lam = 2.0 * max(x, 0.0) / nu * math.sqrt(2.0 * abs(dp) / rho)
    return cq_max * math.tanh(2.0 * lam / lam_crit)


@njit(cache=True)
def stiffness_force(x, F_pre, a, b, c, d):
    """Two-term exponential spring, eq. 4.19, with F_k(0) = F_preload
    (THESIS-ERRATA 17): F_pre + a(e^{bx} - 1) + c(e^{dx} - 1) [N]."""
    return F_pre + a * (math.exp(b * x) - 1.0) + c * (math.exp(d * x) - 1.0)


@njit(cache=True)
def shim_pressure_force(dp, D_d, D_i):
    """Net pressure force on a shim stack, eq. 4.21 with the back pressure
    subtracted (THESIS-ERRATA 19): pi/12 (D_d - D_i)(2 D_d + D_i) dp [N]."""
    return math.pi / 12.0 * (D_d - D_i) * (2.0 * D_d + D_i) * dp


@njit(cache=True)
def intake_pressure_force(dp, D_d, D_h):
    """Pressure force on an intake disc, eq. 4.22 [N]."""
    return math.pi * dp / 4.0 * (D_d * D_d - D_h * D_h)


@njit(cache=True)
def shim_flow_area(x, D_d):
    """Opening area of a shim valve, eq. 4.27 [m^2]."""
    return max(x, 0.0) * math.pi * D_d


@njit(cache=True)
def intake_flow_area(x, D_d, D_i):
    """Opening area of an intake valve, eq. 4.28 as printed (errata 20) [m^2]."""
    return max(x, 0.0) * math.pi * (D_d + D_i)


@njit(cache=True)
def jet_force(cq, A_f, dp, zeta):
    """Flow momentum force, eq. 4.24, acting to open (THESIS-ERRATA 23) [N]."""
    return 2.0 * cq * cq * A_f * dp * math.sin(zeta)


@njit(cache=True)
def stiction_force(x, xdot, mu, x_v0, D_d, D_i):
    """Squeeze-film stiction of an intake disc, eq. 4.25, with X = D_d/D_i > 1
    and mu = rho*nu (THESIS-ERRATA 21). Opposes xdot in both directions [N]."""
    X = D_d / D_i
    X2 = X * X
    X4 = X2 * X2
    bracket = 1.0 - X4 + (1.0 - 2.0 * X2 + X4) / math.log(X)
    gap = max(x, 0.0) + x_v0
    return 3.0 * math.pi * mu / (32.0 * gap * gap * gap) * xdot * D_i ** 4 * bracket


@njit(cache=True)
def dahl_rate(F, xdot, sigma0, F_c, alpha):
    """Dahl friction, eq. 4.26, as a rate: dF/dt = sigma0 (1 - F/F_c sgn(xdot))^alpha xdot.
    The exact sgn is kept (THESIS-ERRATA 22): the rate is continuous because it
    is multiplied by xdot, and |F| <= F_c holds."""
    if xdot == 0.0:
        return 0.0
    s = 1.0 if xdot > 0.0 else -1.0
    base = 1.0 - F / F_c * s
    if base <= 0.0:
        return 0.0
    return sigma0 * base ** alpha * xdot


@njit(cache=True)
def contact_force(x, v, x_max, k_c, c_c, delta):
    """Seat (x < 0) and lift stop (x > x_max) as one-sided penalty contacts
    (THESIS-ERRATA 27). The damping ramps in over ``delta`` of penetration and
    the contact never pulls. Positive = opening direction [N]."""
    f = 0.0
    pen = -x
    if pen > 0.0:
        f += max(0.0, k_c * pen - c_c * min(pen / delta, 1.0) * v)
    pen = x - x_max
    if pen > 0.0:
        f -= max(0.0, k_c * pen + c_c * min(pen / delta, 1.0) * v)
    return f


@njit(cache=True)
def valve_flow(p, o, x, dp, rho, nu, p_tr, use_cq_lambda, use_slot):
    """Flow through one valve [m^3/s] and the share of dp seen by the disc.

    [opening || bleed] in series with the slot (THESIS-ERRATA 25):
    G1 = Cq A_f + Cq_b A_bleed, G2 = Cq_s A_slot, G = G1 G2 / sqrt(G1^2 + G2^2),
    dp_disc = dp G2^2 / (G1^2 + G2^2). Returns (Q, dp_disc, Cq, A_f)."""
    shim = p[o + V_SHIM] > 0.5
    if shim:
        A_f = shim_flow_area(x, p[o + V_DD])
    else:
        A_f = intake_flow_area(x, p[o + V_DD], p[o + V_DI])
    if use_cq_lambda:
        cq = discharge_coefficient(p[o + V_CQ], p[o + V_LAM], x, nu, dp, rho)
    else:
        cq = p[o + V_CQ]
    G1 = cq * A_f + p[o + V_CQB] * p[o + V_AB]
    if use_slot:
        G2 = p[o + V_CQS] * p[o + V_AS]
        s = G1 * G1 + G2 * G2
        G = G1 * G2 / math.sqrt(s)
        dp_disc = dp * G2 * G2 / s
    else:
        G = G1
        dp_disc = dp
    return orifice_flow(G, dp, rho, p_tr), dp_disc, cq, A_f


@njit(cache=True)
def valve_acceleration(p, o, x, v, F_dahl, dp_disc, cq, A_f, mu, zeta, k_c, zeta_c, delta,
                       use_jet, use_stiction, use_friction):
    """Equation of motion eq. 4.20: m x'' = -c x' - F_k + F_st + F_dp - F_mu + F_m + F_contact.
    Returns (x'', dF_dahl/dt)."""
    shim = p[o + V_SHIM] > 0.5
    m = p[o + V_M]
    if shim:
        F_dp = shim_pressure_force(dp_disc, p[o + V_DD], p[o + V_DI])
    else:
        F_dp = intake_pressure_force(dp_disc, p[o + V_DD], p[o + V_DH])
    F = F_dp - p[o + V_C] * v - stiffness_force(x, p[o + V_PRE], p[o + V_A], p[o + V_B], p[o + V_CC], p[o + V_D])
    if use_jet:
        F += jet_force(cq, A_f, dp_disc, zeta)
    if use_stiction and not shim:
        F += stiction_force(x, v, mu, p[o + V_XV0], p[o + V_DD], p[o + V_DI])
    dF = 0.0
    if use_friction and shim:
        F -= F_dahl  # friction opposes motion (THESIS-ERRATA 22)
        dF = dahl_rate(F_dahl, v, p[o + V_SIG], p[o + V_FC], p[o + V_ALPHA])
    c_c = 2.0 * zeta_c * math.sqrt(k_c * m)
    F += contact_force(x, v, p[o + V_XMAX], k_c, c_c, delta)
    return F / m, dF
