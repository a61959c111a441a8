"""Assembled right-hand side for the three configurations (thesis ch. 4).

- ``valve``  (flow bench): one valve between an upstream volume fed with a
  prescribed flow and a constant back pressure.
- ``damper`` (rod fixed, eq. 4.1): tube displacement u(t) prescribed, the
  stroke is s = u; the output force is the rod force.
- ``module`` (eq. 4.4): tube displacement prescribed at the lower mount, the
  rod is a mass on the top mount; s = u - x_rod (THESIS-ERRATA 5).

``evaluate`` fills the state derivative ``dy`` and the output channels
``out`` (layout.OUTPUTS) for one (t, y). Everything in SI.
"""

from __future__ import annotations

import math

from numba import njit

from .active_valve import active_valve_flow
from .chambers import cavitation_factor, chamber_volumes, pressure_rate, rod_force
from .fluid import emulsion_bulk_modulus, gas_spring_pressure, series_bulk_modulus, wall_bulk_modulus
from .layout import (
    B_F, B_P, B_V, B_X, CFG_MODULE, CFG_SOLVER_TEST, CFG_TOPMOUNT, CFG_VALVE, T_W, T_X, T_Y,
    O_A_ROD, O_DVG, O_F_D, O_F_MU, O_F_TM, O_P_B, O_P_C, O_P_R, O_P_RES, O_Q0, O_Q_A, O_Q_BP,
    O_S, O_ST_B, O_ST_C, O_ST_R, O_U, O_V, O_X0,
    P_A_B, P_A_BP, P_A_R, P_BENCH_P_DOWN, P_BENCH_V, P_BENCH_VALVE, P_CHI, P_CQ_BP, P_CURRENT,
    P_DELTA_C, P_E_CAV, P_E_CQ, P_E_GAS, P_E_JET, P_E_ROD_FRICTION, P_E_SHIM_FRICTION, P_E_SLOT,
    P_E_STICTION, P_E_TM_DYNAMICS, P_E_WALL, P_EX_DT, P_EX_T0, P_FR_ALPHAS, P_FR_AS, P_FR_CCOMP,
    P_FR_FC, P_FR_FS, P_FR_KB, P_FR_S2, P_FR_VD, P_GAMMA, P_K_C, P_K_OIL, P_L_C0, P_L_R0, P_M_ROD,
    P_NU, P_P0, P_P_ATM, P_P_REF, P_P_SAT, P_P_VAP, P_PSI_PT, P_PSI_TT, P_RATIO_TT, P_RHO, P_T_REF,
    P_TEMP, P_TM_C0, P_TM_C1, P_TM_C2, P_TM_FLD0, P_TM_K0, P_TM_K1, P_TM_K2, P_TM_P0, P_TM_P1,
    P_TM_P2, P_TM_Q0, P_TM_Q1, P_TM_Q2, P_TM_R, P_TM_WU, P_TM_YU, P_V_B, P_V_G0, P_VALVES,
    P_ZETA, P_ZETA_C, P_P_TR, P_E_LEAK, P_G_LEAK,
    S_DAHL_BC, S_DAHL_PR, S_PB, S_PC, S_PR, S_TMW, S_TMX, S_TMY, S_VG, S_VROD, S_X0, S_XROD, S_Z,
)
from .rod_friction import lugre
from .top_mount import top_mount_force, top_mount_rates
from .valves import V_SIZE, valve_acceleration, valve_flow


@njit(cache=True)
def excitation_at(t, p, ex):
    """Prescribed input and its rate at t: cubic Hermite through samples
    ex[0] (value) and ex[1] (rate) spaced EX_DT from EX_T0; held outside."""
    n = ex.shape[1]
    dt = p[P_EX_DT]
    r = (t - p[P_EX_T0]) / dt
    if r <= 0.0:
        return ex[0, 0], ex[1, 0]
    k = int(r)
    if k >= n - 1:
        if r <= n - 1 + 1e-9:  # the last sample itself
            return ex[0, n - 1], ex[1, n - 1]
        return ex[0, n - 1], 0.0
    s = r - k
    s2 = s * s
    s3 = s2 * s
    u0 = ex[0, k]
    u1 = ex[0, k + 1]
    m0 = ex[1, k] * dt
    m1 = ex[1, k + 1] * dt
    u = (2 * s3 - 3 * s2 + 1) * u0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * u1 + (s3 - s2) * m1
    du = ((6 * s2 - 6 * s) * u0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * u1 + (3 * s2 - 2 * s) * m1) / dt
    return u, du


@njit(cache=True)
def fluid_modulus(P, p):
    """Emulsion modulus (eq. 4.14-4.16) at absolute pressure P, or K_oil
    when the gas-content effect is off."""
    if p[P_E_GAS] > 0.5:
        return emulsion_bulk_modulus(P, p[P_K_OIL], p[P_CHI], p[P_P_SAT], p[P_P_VAP], p[P_P_REF],
                                     p[P_TEMP], p[P_T_REF], p[P_GAMMA])
    return p[P_K_OIL]


@njit(cache=True)
def _valve(p, k, x, v, F_dahl, p1, p2):
    """Flow and state rates of valve k between upstream p1 and downstream p2."""
    o = P_VALVES + k * V_SIZE
    rho = p[P_RHO]
    Q, dp_disc, cq, A_f = valve_flow(p, o, x, p1 - p2, rho, p[P_NU], p[P_P_TR],
                                     p[P_E_CQ] > 0.5, p[P_E_SLOT] > 0.5)
    a, dF = valve_acceleration(p, o, x, v, F_dahl, dp_disc, cq, A_f, rho * p[P_NU], p[P_ZETA],
                               p[P_K_C], p[P_ZETA_C], p[P_DELTA_C], p[P_E_JET] > 0.5,
                               p[P_E_STICTION] > 0.5, p[P_E_SHIM_FRICTION] > 0.5)
    return Q, a, dF


@njit(cache=True)
def evaluate(t, y, p, ex, mc, md, mq, cfg, dy, out):
    """State derivative dy and output channels out at (t, y)."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    if cfg == CFG_VALVE:
        _evaluate_bench(t, y, p, ex, dy, out)
        return
    if cfg == CFG_SOLVER_TEST:
        _evaluate_test_problem(t, y, p, dy, out)
        return
    if cfg == CFG_TOPMOUNT:
        _evaluate_top_mount(t, y, p, ex, dy, out)
        return
    u, du = excitation_at(t, p, ex)
    module = cfg == CFG_MODULE
    if module:
        s = u - y[S_XROD]
        sd = du - y[S_VROD]
    else:
        s = u
        sd = du
    A_r = p[P_A_R]
    A_b = p[P_A_B]
    P_r = y[S_PR]
    P_c = y[S_PC]
    P_b = y[S_PB]
    P_res = gas_spring_pressure(p[P_P0], p[P_V_G0], y[S_VG], p[P_GAMMA])

    # valves (eq. 4.19-4.31): 0 piston rebound r->c, 1 piston intake c->r,
    # 2 base compression c->res, 3 base intake res->c
    Q0, a0, dF0 = _valve(p, 0, y[S_X0], y[S_X0 + 1], y[S_DAHL_PR], P_r, P_c)
    Q1, a1, _ = _valve(p, 1, y[S_X0 + 2], y[S_X0 + 3], 0.0, P_c, P_r)
    Q2, a2, dF2 = _valve(p, 2, y[S_X0 + 4], y[S_X0 + 5], y[S_DAHL_BC], P_c, P_res)
    Q3, a3, _ = _valve(p, 3, y[S_X0 + 6], y[S_X0 + 7], 0.0, P_res, P_c)
    Q_p = Q0 - Q1  # rebound -> compression (THESIS-ERRATA 7)
    if p[P_E_LEAK] > 0.5:  # laminar leakage past the piston band (not in the thesis model)
        Q_p += p[P_G_LEAK] * (P_r - P_c)
    Q_bv = Q2 - Q3  # compression -> reserve
    rho = p[P_RHO]
    G_bp = p[P_CQ_BP] * p[P_A_BP]
    Q_bp = G_bp * math.sqrt(2.0 / rho) * (P_r - P_b) / ((P_r - P_b) ** 2 + p[P_P_TR] ** 2) ** 0.25
    Q_a = active_valve_flow(p[P_CURRENT], P_b - P_res, mc, md, mq)

    # compliance (eq. 4.13-4.18)
    K_r = fluid_modulus(P_r, p)
    K_c = fluid_modulus(P_c, p)
    K_b = fluid_modulus(P_b, p)
    if p[P_E_WALL] > 0.5:
        K_c = series_bulk_modulus(K_c, wall_bulk_modulus(p[P_PSI_PT], P_c - P_res, 1.0))
        K_b = series_bulk_modulus(K_b, wall_bulk_modulus(p[P_PSI_TT], P_b - P_res, p[P_RATIO_TT]))
    if p[P_E_CAV] > 0.5:
        K_r *= cavitation_factor(P_r, p[P_P_VAP])
        K_c *= cavitation_factor(P_c, p[P_P_VAP])
        K_b *= cavitation_factor(P_b, p[P_P_VAP])

    # chambers (eq. 4.5-4.12)
    V_r, V_c = chamber_volumes(s, A_r, A_b, p[P_L_R0], p[P_L_C0])
    dV_r = -A_r * sd
    dV_c = A_b * sd
    dy[S_PR] = pressure_rate(K_r, V_r, dV_r, Q_p + Q_bp)
    dy[S_PC] = pressure_rate(K_c, V_c, dV_c, -Q_p + Q_bv)
    dy[S_PB] = pressure_rate(K_b, p[P_V_B], 0.0, Q_a - Q_bp)
    dy[S_VG] = -(Q_bv + Q_a)  # reserve gas (THESIS-ERRATA 8)
    dy[S_X0] = y[S_X0 + 1]
    dy[S_X0 + 1] = a0
    dy[S_X0 + 2] = y[S_X0 + 3]
    dy[S_X0 + 3] = a1
    dy[S_X0 + 4] = y[S_X0 + 5]
    dy[S_X0 + 5] = a2
    dy[S_X0 + 6] = y[S_X0 + 7]
    dy[S_X0 + 7] = a3
    dy[S_DAHL_PR] = dF0
    dy[S_DAHL_BC] = dF2

    # rod friction (eq. 4.38-4.41)
    F_mu = 0.0
    dy[S_Z] = 0.0
    if p[P_E_ROD_FRICTION] > 0.5:
        dz, F_mu = lugre(y[S_Z], sd, p[P_FR_KB], p[P_FR_FC], p[P_FR_FS], p[P_FR_S2], p[P_FR_CCOMP],
                         p[P_FR_VD], p[P_FR_AS], p[P_FR_ALPHAS])
        dy[S_Z] = dz
    F_d = rod_force(P_r, P_c, A_r, A_b, p[P_P_ATM], F_mu)  # eq. 4.1

    F_tm = 0.0
    a_rod = 0.0
    if module:
        # top mount (eq. 4.32-4.37) and rod equation of motion (eq. 4.4)
        xd, yd, wd, F_tm = _tm_force(p, y[S_XROD], y[S_VROD], y[S_TMX], y[S_TMY], y[S_TMW])
        a_rod = (F_d - F_tm) / p[P_M_ROD]
        dy[S_XROD] = y[S_VROD]
        dy[S_VROD] = a_rod
        if p[P_E_TM_DYNAMICS] > 0.5:
            dy[S_TMX] = xd
            dy[S_TMY] = yd
            dy[S_TMW] = wd
        else:
            dy[S_TMX] = 0.0
            dy[S_TMY] = 0.0
            dy[S_TMW] = 0.0

    out[O_U] = u
    out[O_V] = du
    out[O_S] = s
    out[O_F_D] = F_d
    out[O_F_TM] = F_tm
    out[O_A_ROD] = -a_rod  # reported positive up (THESIS-ERRATA 5)
    out[O_F_MU] = F_mu
    out[O_P_R] = P_r
    out[O_P_C] = P_c
    out[O_P_B] = P_b
    out[O_P_RES] = P_res
    for k in range(4):
        out[O_X0 + k] = y[S_X0 + 2 * k]
    out[O_Q0] = Q0
    out[O_Q0 + 1] = Q1
    out[O_Q0 + 2] = Q2
    out[O_Q0 + 3] = Q3
    out[O_Q_BP] = Q_bp
    out[O_Q_A] = Q_a
    out[O_ST_R] = V_r / K_r * dy[S_PR]
    out[O_ST_C] = V_c / K_c * dy[S_PC]
    out[O_ST_B] = p[P_V_B] / K_b * dy[S_PB]
    out[O_DVG] = dy[S_VG]


@njit(cache=True)
def _evaluate_bench(t, y, p, ex, dy, out):
    """Flow bench (thesis 2.7.2, 6.2.1): prescribed flow Q_in into an
    upstream volume of gas-free oil, one valve to a constant back pressure."""
    Q_in, dQ = excitation_at(t, p, ex)
    k = int(p[P_BENCH_VALVE])
    P_up = y[B_P]
    P_dn = p[P_BENCH_P_DOWN]
    Q, a, dF = _valve(p, k, y[B_X], y[B_V], y[B_F], P_up, P_dn)
    K = p[P_K_OIL]  # degassed oil (THESIS-ERRATA 37)
    if p[P_E_CAV] > 0.5:
        K *= cavitation_factor(P_up, p[P_P_VAP])
    dy[B_P] = pressure_rate(K, p[P_BENCH_V], 0.0, Q - Q_in)
    dy[B_X] = y[B_V]
    dy[B_V] = a
    dy[B_F] = dF
    out[O_U] = Q_in
    out[O_V] = dQ
    out[O_P_R] = P_up
    out[O_P_C] = P_dn
    out[O_X0] = y[B_X]
    out[O_Q0] = Q


@njit(cache=True)
def _tm_force(p, X, Xdot, x, y, w):
    """Top-mount rates (eq. 4.32-4.34) and force (eq. 4.35-4.37)."""
    xd, yd, wd = top_mount_rates(Xdot, x, y, w, p[P_TM_R], p[P_TM_K0], p[P_TM_K1], p[P_TM_K2],
                                 p[P_TM_C0], p[P_TM_C1], p[P_TM_C2])
    F = top_mount_force(X, y, wd, p[P_TM_P0], p[P_TM_P1], p[P_TM_P2], p[P_TM_Q0], p[P_TM_Q1], p[P_TM_Q2],
                        p[P_TM_K0], p[P_TM_C0], p[P_TM_YU], p[P_TM_WU], p[P_TM_FLD0:P_TM_FLD0 + 5],
                        p[P_E_TM_DYNAMICS] > 0.5)
    return xd, yd, wd, F


@njit(cache=True)
def _evaluate_top_mount(t, y, p, ex, dy, out):
    """Top-mount test bench (thesis 6.4): deflection X(t) prescribed, force out."""
    X, Xd = excitation_at(t, p, ex)
    xd, yd, wd, F = _tm_force(p, X, Xd, y[T_X], y[T_Y], y[T_W])
    dyn = p[P_E_TM_DYNAMICS] > 0.5
    dy[T_X] = xd if dyn else 0.0
    dy[T_Y] = yd if dyn else 0.0
    dy[T_W] = wd if dyn else 0.0
    out[O_U] = X
    out[O_V] = Xd
    out[O_F_TM] = F


@njit(cache=True)
def _evaluate_test_problem(t, y, p, dy, out):
    """Solver check (not a damper): Prothero-Robinson y0' = -lam (y0 - sin t) + cos t
    (exact y0 = sin t for y0(0) = 0, stiffness lam = p[0]) and an undamped
    oscillator y1'' = -w^2 y1 with w = p[1] (exact y1 = cos(w t))."""
    lam = p[0]
    w = p[1]
    dy[0] = -lam * (y[0] - math.sin(t)) + math.cos(t)
    dy[1] = y[2]
    dy[2] = -w * w * y[1]
    out[0] = y[0]
    out[1] = y[1]
