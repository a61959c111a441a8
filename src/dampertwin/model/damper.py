"""Assembled right-hand side for the three configurations (thesis ch. 4).

- ``valve``  (flow bench): one valve between an upstream volume fed with a
  prescribed flow and a constant back pressure.
- ``damper`` (rod fixed, eq. 4.1): tube displacement u(t) prescribed, the
  stroke is s = u; the output force is the rod force.
- ``module`` (eq. 4.4): tube displacement prescribed at the lower mount, the
  rod is a mass on the top mount; s = u - x_rod (THESIS-ERRATA 5).

Each configuration is one compiled right-hand side ``rhs_<cfg>(t, y, p, ex,
aux, dy, out)`` with the solver's signature (``solver.rhs_signature``): it
fills the state derivative ``dy`` and the output channels ``out``
(layout.OUTPUTS) for one (t, y). ``aux`` is the active-valve map
(``active_valve.pack_map``). Everything in SI.
"""

from __future__ import annotations

import math

from numba import njit

from ..solver import rhs_signature
from .active_valve import map_flow
from .bench import upstream_pressure_rate
from .chambers import cavitation_factor, chamber_volumes, pressure_rate, rod_force
from .fluid import emulsion_bulk_modulus, gas_spring_pressure, series_bulk_modulus, wall_bulk_modulus
from .inputs import hermite
from .layout import N_OUT, B, O, P, S, T
from .piston_leakage import leakage_flow
from .rod import rod_acceleration
from .rod_friction import lugre
from .top_mount import N_FLD, top_mount_force, top_mount_rates
from .valves import V_SIZE, orifice_flow, valve_acceleration, valve_flow

SIGNATURE = rhs_signature()


@njit(cache=True, error_model="numpy")
def excitation_at(t, p, ex):
    """Prescribed input and its rate at t (inputs.hermite on the test's grid)."""
    return hermite(t, p[P.EX_T0], p[P.EX_DT], ex)


@njit(cache=True, error_model="numpy")
def fluid_modulus(pressure, p):
    """Emulsion modulus (eq. 4.14-4.16) at absolute pressure [Pa], or K_oil
    when the gas-content effect is off."""
    if p[P.E_GAS] > 0.5:
        return emulsion_bulk_modulus(pressure, p[P.K_OIL], p[P.CHI], p[P.P_SAT], p[P.P_VAP], p[P.P_REF],
                                     p[P.TEMP], p[P.T_REF], p[P.GAMMA])
    return p[P.K_OIL]


@njit(cache=True, error_model="numpy")
def _valve(p, k, x, v, F_dahl, p1, p2):
    """Flow and state rates of valve k between upstream p1 and downstream p2."""
    o = P.VALVES + k * V_SIZE
    rho = p[P.RHO]
    Q, dp_disc, cq, A_f = valve_flow(p, o, x, p1 - p2, rho, p[P.NU], p[P.P_TR],
                                     p[P.E_CQ] > 0.5, p[P.E_SLOT] > 0.5)
    a, dF = valve_acceleration(p, o, x, v, F_dahl, dp_disc, cq, A_f, rho * p[P.NU], p[P.ZETA],
                               p[P.K_C], p[P.ZETA_C], p[P.DELTA_C], p[P.E_JET] > 0.5,
                               p[P.E_STICTION] > 0.5, p[P.E_SHIM_FRICTION] > 0.5)
    return Q, a, dF


@njit(cache=True, error_model="numpy")
def _tm_force(p, X, Xdot, x, y, w):
    """Top-mount rates (eq. 4.32-4.34) and force (eq. 4.35-4.37)."""
    xd, yd, wd = top_mount_rates(Xdot, x, y, w, p[P.TM_R], p[P.TM_K0], p[P.TM_K1], p[P.TM_K2],
                                 p[P.TM_C0], p[P.TM_C1], p[P.TM_C2])
    F = top_mount_force(X, y, wd, p[P.TM_P0], p[P.TM_P1], p[P.TM_P2], p[P.TM_Q0], p[P.TM_Q1], p[P.TM_Q2],
                        p[P.TM_K0], p[P.TM_C0], p[P.TM_YU], p[P.TM_WU], p[P.TM_FLD0:P.TM_FLD0 + N_FLD],
                        p[P.E_TM_DYNAMICS] > 0.5)
    return xd, yd, wd, F


@njit(cache=True, error_model="numpy")
def _damper(t, y, p, ex, aux, dy, out, module):
    """Damper (rod fixed, eq. 4.1: stroke s = u) or module (eq. 4.4: the rod
    on the top mount, s = u - x_rod)."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    u, du = excitation_at(t, p, ex)
    if module:
        s = u - y[S.x_rod]
        sd = du - y[S.v_rod]
    else:
        s = u
        sd = du
    A_r = p[P.A_R]
    A_b = p[P.A_B]
    P_r = y[S.P_r]
    P_c = y[S.P_c]
    P_b = y[S.P_b]
    P_res = gas_spring_pressure(p[P.P0], p[P.V_G0], y[S.V_g], p[P.GAMMA])

    # valves (eq. 4.19-4.31): 0 piston rebound r->c, 1 piston intake c->r,
    # 2 base compression c->res, 3 base intake res->c
    Q0, a0, dF0 = _valve(p, 0, y[S.x_piston_rebound], y[S.v_piston_rebound], y[S.F_dahl_piston_rebound], P_r, P_c)
    Q1, a1, _ = _valve(p, 1, y[S.x_piston_intake], y[S.v_piston_intake], 0.0, P_c, P_r)
    Q2, a2, dF2 = _valve(p, 2, y[S.x_base_compression], y[S.v_base_compression], y[S.F_dahl_base_compression],
                         P_c, P_res)
    Q3, a3, _ = _valve(p, 3, y[S.x_base_intake], y[S.v_base_intake], 0.0, P_res, P_c)
    Q_p = Q0 - Q1  # rebound -> compression (THESIS-ERRATA 7)
    if p[P.E_LEAK] > 0.5:
        Q_p += leakage_flow(p[P.G_LEAK], P_r, P_c)
    Q_bv = Q2 - Q3  # compression -> reserve
    Q_bp = orifice_flow(p[P.CQ_BP] * p[P.A_BP], P_r - P_b, p[P.RHO], p[P.P_TR])
    Q_a = map_flow(p[P.CURRENT], P_b - P_res, aux)

    # compliance (eq. 4.13-4.18)
    K_r = fluid_modulus(P_r, p)
    K_c = fluid_modulus(P_c, p)
    K_b = fluid_modulus(P_b, p)
    if p[P.E_WALL] > 0.5:
        K_c = series_bulk_modulus(K_c, wall_bulk_modulus(p[P.PSI_PT], P_c - P_res, 1.0))
        K_b = series_bulk_modulus(K_b, wall_bulk_modulus(p[P.PSI_TT], P_b - P_res, p[P.RATIO_TT]))
    if p[P.E_CAV] > 0.5:
        K_r *= cavitation_factor(P_r, p[P.P_VAP])
        K_c *= cavitation_factor(P_c, p[P.P_VAP])
        K_b *= cavitation_factor(P_b, p[P.P_VAP])

    # chambers (eq. 4.5-4.12)
    V_r, V_c = chamber_volumes(s, A_r, A_b, p[P.L_R0], p[P.L_C0])
    dV_r = -A_r * sd
    dV_c = A_b * sd
    dy[S.P_r] = pressure_rate(K_r, V_r, dV_r, Q_p + Q_bp)
    dy[S.P_c] = pressure_rate(K_c, V_c, dV_c, -Q_p + Q_bv)
    dy[S.P_b] = pressure_rate(K_b, p[P.V_B], 0.0, Q_a - Q_bp)
    dy[S.V_g] = -(Q_bv + Q_a)  # reserve gas (THESIS-ERRATA 8)
    dy[S.x_piston_rebound] = y[S.v_piston_rebound]
    dy[S.v_piston_rebound] = a0
    dy[S.F_dahl_piston_rebound] = dF0
    dy[S.x_piston_intake] = y[S.v_piston_intake]
    dy[S.v_piston_intake] = a1
    dy[S.x_base_compression] = y[S.v_base_compression]
    dy[S.v_base_compression] = a2
    dy[S.F_dahl_base_compression] = dF2
    dy[S.x_base_intake] = y[S.v_base_intake]
    dy[S.v_base_intake] = a3

    # rod friction (eq. 4.38-4.41)
    F_mu = 0.0
    dy[S.z] = 0.0
    if p[P.E_ROD_FRICTION] > 0.5:
        dz, F_mu = lugre(y[S.z], sd, p[P.FR_KB], p[P.FR_FC], p[P.FR_FS], p[P.FR_S2], p[P.FR_CCOMP],
                         p[P.FR_VD], p[P.FR_AS], p[P.FR_ALPHAS])
        dy[S.z] = dz
    F_d = rod_force(P_r, P_c, A_r, A_b, p[P.P_ATM], F_mu)  # eq. 4.1

    F_tm = 0.0
    a_rod = 0.0
    if module:
        # top mount (eq. 4.32-4.37) and rod equation of motion (eq. 4.4)
        xd, yd, wd, F_tm = _tm_force(p, y[S.x_rod], y[S.v_rod], y[S.tm_x], y[S.tm_y], y[S.tm_w])
        a_rod = rod_acceleration(F_d, F_tm, p[P.M_ROD])
        dy[S.x_rod] = y[S.v_rod]
        dy[S.v_rod] = a_rod
        dyn = p[P.E_TM_DYNAMICS] > 0.5
        dy[S.tm_x] = xd if dyn else 0.0
        dy[S.tm_y] = yd if dyn else 0.0
        dy[S.tm_w] = wd if dyn else 0.0

    out[O.U] = u
    out[O.V] = du
    out[O.S] = s
    out[O.F_D] = F_d
    out[O.F_TM] = F_tm
    out[O.A_ROD] = -a_rod  # reported positive up (THESIS-ERRATA 5)
    out[O.F_MU] = F_mu
    out[O.P_R] = P_r
    out[O.P_C] = P_c
    out[O.P_B] = P_b
    out[O.P_RES] = P_res
    out[O.X0] = y[S.x_piston_rebound]
    out[O.X1] = y[S.x_piston_intake]
    out[O.X2] = y[S.x_base_compression]
    out[O.X3] = y[S.x_base_intake]
    out[O.Q0] = Q0
    out[O.Q1] = Q1
    out[O.Q2] = Q2
    out[O.Q3] = Q3
    out[O.Q_BP] = Q_bp
    out[O.Q_A] = Q_a
    out[O.ST_R] = V_r / K_r * dy[S.P_r]
    out[O.ST_C] = V_c / K_c * dy[S.P_c]
    out[O.ST_B] = p[P.V_B] / K_b * dy[S.P_b]
    out[O.DVG] = dy[S.V_g]


@njit(SIGNATURE, cache=True, error_model="numpy")
def rhs_damper(t, y, p, ex, aux, dy, out):
    """Damper configuration: tube displacement prescribed, rod fixed."""
    _damper(t, y, p, ex, aux, dy, out, False)


@njit(SIGNATURE, cache=True, error_model="numpy")
def rhs_module(t, y, p, ex, aux, dy, out):
    """Module configuration: the rod on the top mount (eq. 4.4)."""
    _damper(t, y, p, ex, aux, dy, out, True)


@njit(SIGNATURE, cache=True, error_model="numpy")
def rhs_valve(t, y, p, ex, aux, dy, out):
    """Flow bench (thesis 2.7.2, 6.2.1): prescribed flow Q_in into an
    upstream volume of gas-free oil, one valve to a constant back pressure."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    Q_in, dQ = excitation_at(t, p, ex)
    k = int(p[P.BENCH_VALVE])
    P_up = y[B.P_up]
    P_dn = p[P.BENCH_P_DOWN]
    Q, a, dF = _valve(p, k, y[B.x], y[B.v], y[B.F_dahl], P_up, P_dn)
    K = p[P.K_OIL]  # degassed oil (THESIS-ERRATA 37)
    if p[P.E_CAV] > 0.5:
        K *= cavitation_factor(P_up, p[P.P_VAP])
    dy[B.P_up] = upstream_pressure_rate(K, p[P.BENCH_V], Q, Q_in)
    dy[B.x] = y[B.v]
    dy[B.v] = a
    dy[B.F_dahl] = dF
    out[O.U] = Q_in
    out[O.V] = dQ
    out[O.P_R] = P_up
    out[O.P_C] = P_dn
    out[O.X0] = y[B.x]
    out[O.Q0] = Q


@njit(SIGNATURE, cache=True, error_model="numpy")
def rhs_topmount(t, y, p, ex, aux, dy, out):
    """Top-mount test bench (thesis 6.4): deflection X(t) prescribed, force out."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    X, Xd = excitation_at(t, p, ex)
    xd, yd, wd, F = _tm_force(p, X, Xd, y[T.tm_x], y[T.tm_y], y[T.tm_w])
    dyn = p[P.E_TM_DYNAMICS] > 0.5
    dy[T.tm_x] = xd if dyn else 0.0
    dy[T.tm_y] = yd if dyn else 0.0
    dy[T.tm_w] = wd if dyn else 0.0
    out[O.U] = X
    out[O.V] = Xd
    out[O.F_TM] = F


RHS = {"valve": rhs_valve, "damper": rhs_damper, "module": rhs_module, "topmount": rhs_topmount}
