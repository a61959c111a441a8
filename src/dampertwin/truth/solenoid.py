"""Pilot-operated solenoid valve of the truth (the damper's active valve).

Driver: a PI current loop (gains KP [V/A], KI [V/(A s)]) whose output
voltage saturates smoothly at the supply U_MAX; its closed-loop bandwidth
is finite (~ (R + KP) / (2 pi L)). Coil: L di/dt = u - R i (an R-L
circuit). Switched off (effect ``current_driver``), an ideal current
source: the current is the command, no driver or coil dynamics.
Magnetic force: F = F_S r^2 / sqrt(1 + r^2), r = i / I_S: square
law while the iron is unsaturated, linear (the proportional-solenoid
range) once it saturates (Vaughan & Gamble, ASME J. Dyn. Syst. Meas. Control
118 (1996) 705; Manring, Hydraulic Control Systems, 2005, 6.2). Pilot: a
poppet of seat diameter D_PL, mass M_P, opening spring (preload F_P0, rate
K_P), viscous damping C_P, closed by the magnetic force and by its flow
force 2 CdA dp cos(theta) (Merritt 1967 5.3), as is the main stage. It relieves a control chamber
(volume V_K) fed from the inlet through a fixed orifice A_F. Main stage: a
disc (mass M_M, seat diameter D_M, inlet area A_M inside the seat, control
area A_K behind it, spring K_M with preload F_M0) that opens when the inlet
pressure overcomes the control pressure: it follows the pilot pressure. A
bleed A_B bypasses the stage. Each pressure-loaded area sweeps its volume
(virtual work): the main stage A_M on the inlet, A_K in the control chamber,
A_K - A_M on the outlet; the pilot poppet's seat area pi D_PL^2 / 4 in the
control chamber and the outlet (:func:`pilot_area`; the caller's volumes).
The flow forces' work on the poppets is taken from the flows' dissipation. The valve's static P/Q map is not an input:
it emerges from these parts.
"""

from __future__ import annotations

import math

from numba import njit

from .fluid import JIT, hunt_crossley, radial_gap_resistance, ramp, throttle

PARAMS = ("R", "L", "KP", "KI", "U_MAX", "F_S", "I_S", "D_PL", "W_PL", "M_P", "K_P", "F_P0", "C_P", "XP_MAX",
          "COS_JET", "A_F", "L_F", "V_K", "D_M", "W_M", "A_M", "A_K", "M_M", "K_M", "F_M0", "C_M", "XM_MAX",
          "A_B", "L_B", "CD", "K_C", "LAM_C", "EPS", "DRIVER")
(R, L, KP, KI, U_MAX, F_S, I_S, D_PL, W_PL, M_P, K_P, F_P0, C_P, XP_MAX, COS_JET, A_F, L_F, V_K, D_M, W_M, A_M,
 A_K, M_M, K_M, F_M0, C_M, XM_MAX, A_B, L_B, CD, K_C, LAM_C, EPS, DRIVER) = range(len(PARAMS))
STATES = (("i", "A", 0.1, "coil current"), ("e", "A s", 1e-3, "driver's integrated current error"),
          ("x_p", "m", 1e-5, "pilot lift"), ("v_p", "m/s", 0.01, "pilot velocity"),
          ("P_k", "Pa", 1e5, "control chamber pressure"), ("x_m", "m", 1e-4, "main stage lift"),
          ("v_m", "m/s", 0.1, "main stage velocity"))
I, E, XP, VP, PK, XM, VM = range(len(STATES))
GAP_EPS = 1e-7  # [m] rounding of the lifts in the flow laws


@njit(**JIT)
def coil(i, e, i_cmd, p, o):
    """(di/dt, de/dt) of the R-L coil behind the PI current driver. With
    DRIVER off the coil is fed by an ideal current source: no electrical
    dynamics, the current is the command (:func:`coil_current`), rates 0."""
    if p[o + DRIVER] > 0.5:
        u = p[o + U_MAX] * math.tanh((p[o + KP] * (i_cmd - i) + p[o + KI] * e) / p[o + U_MAX])
        return (u - p[o + R] * i) / p[o + L], i_cmd - i
    return 0.0, 0.0


@njit(**JIT)
def coil_current(i, i_cmd, p, o):
    """The coil's current [A]: the state behind the driver, or the command
    itself with DRIVER off (an ideal current source)."""
    return i if p[o + DRIVER] > 0.5 else i_cmd


@njit(**JIT)
def magnetic_force(i, p, o):
    """Solenoid force [N]: square law, linear once saturated."""
    r2 = (i / p[o + I_S]) ** 2
    return p[o + F_S] * r2 / math.sqrt(1.0 + r2)


@njit(**JIT)
def pilot_area(p, o):
    """Pressure-loaded area of the pilot poppet on its seat [m^2]: the
    control chamber's volume grows by it per unit pilot lift, the outlet's
    shrinks by it."""
    return 0.25 * math.pi * p[o + D_PL] ** 2


@njit(**JIT)
def _duct(mu, area, length):
    r = math.sqrt(area / math.pi)
    return 8.0 * mu * length / (math.pi * r ** 4)


@njit(**JIT)
def active_valve(y, s, p, o, i_cmd, P_in, P_out, rho, mu, dy):
    """Writes the valve's mechanical and electrical state rates (the control
    pressure's rate is the caller's, chambers.pressure_rate). Returns (main +
    bleed flow, feed flow, pilot flow [m^3/s], magnetic power into the
    pilot [W], dissipated power [W])."""
    di, de = coil(y[s + I], y[s + E], i_cmd, p, o)
    dy[s + I] = di
    dy[s + E] = de
    F_mag = magnetic_force(coil_current(y[s + I], i_cmd, p, o), p, o)
    xp = y[s + XP]
    vp = y[s + VP]
    Pk = y[s + PK]
    xm = y[s + XM]
    vm = y[s + VM]
    cd = p[o + CD]
    # pilot poppet
    hp = ramp(xp, GAP_EPS)
    rp = 0.5 * p[o + D_PL]
    A_p = cd * math.pi * p[o + D_PL] * hp
    Q_p = throttle(Pk - P_out, radial_gap_resistance(mu, rp, rp + p[o + W_PL], hp), A_p, rho)
    F_flow = 2.0 * A_p * (Pk - P_out) * p[o + COS_JET] * A_p * A_p / (A_p * A_p + (cd * math.pi * rp * rp) ** 2)
    Fs, Ds = hunt_crossley(-xp, -vp, p[o + K_C], p[o + LAM_C], p[o + EPS])
    Ft, Dt = hunt_crossley(xp - p[o + XP_MAX], vp, p[o + K_C], p[o + LAM_C], p[o + EPS])
    f_p = ((Pk - P_out) * pilot_area(p, o) + p[o + F_P0] - p[o + K_P] * xp - F_mag - F_flow + Fs - Ft
           - p[o + C_P] * vp)
    dy[s + XP] = vp
    dy[s + VP] = f_p / p[o + M_P]
    # main stage
    hm = ramp(xm, GAP_EPS)
    rm = 0.5 * p[o + D_M]
    A_mn = cd * math.pi * p[o + D_M] * hm
    Q_m = throttle(P_in - P_out, radial_gap_resistance(mu, rm, rm + p[o + W_M], hm), A_mn, rho)
    Q_b = throttle(P_in - P_out, _duct(mu, p[o + A_B], p[o + L_B]), cd * p[o + A_B], rho)
    Q_f = throttle(P_in - Pk, _duct(mu, p[o + A_F], p[o + L_F]), cd * p[o + A_F], rho)
    Gs, Gds = hunt_crossley(-xm, -vm, p[o + K_C], p[o + LAM_C], p[o + EPS])
    Gt, Gdt = hunt_crossley(xm - p[o + XM_MAX], vm, p[o + K_C], p[o + LAM_C], p[o + EPS])
    F_flow_m = 2.0 * A_mn * (P_in - P_out) * p[o + COS_JET]  # the main jet's closing flow force (Merritt 5.3)
    f_m = (P_in * p[o + A_M] + P_out * (p[o + A_K] - p[o + A_M]) - Pk * p[o + A_K] - p[o + F_M0] - p[o + K_M] * xm
           - F_flow_m + Gs - Gt - p[o + C_M] * vm)
    dy[s + XM] = vm
    dy[s + VM] = f_m / p[o + M_M]
    loss = ((P_in - P_out) * (Q_m + Q_b) + (P_in - Pk) * Q_f + (Pk - P_out) * Q_p + p[o + C_P] * vp * vp
            + p[o + C_M] * vm * vm + Ds + Dt + Gds + Gdt + F_flow * vp + F_flow_m * vm)
    return Q_m + Q_b, Q_f, Q_p, -F_mag * vp, loss
