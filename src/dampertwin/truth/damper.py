"""Assembled right-hand sides of the truth (solver.rhs_signature):
``valve`` (flow bench), ``damper`` (rod on the fixture's crosshead, tube
driven), ``module`` (rod on the top mount, the mount on the crosshead) and
``topmount`` (the mount alone on the crosshead); ``damper+`` / ``module+``
the same with the hidden effects' states appended (layout.EXT_BLOCKS: the
steel node, the entrained gas, the top-mount sleeve), run only when one of
those effects is on; ``damper_fp`` / ``module_fp`` a mono tube's (its
floating piston's states after the extension). They compile at first use,
not at import (``dampertwin.jit``).

The architecture (``chambers.ARCH``, passive.py): the triple tube of the
thesis; a twin tube without the third tube's chamber, bypass and active
valve (their states rest); a mono tube also without the base valves, its
compression chamber on the floating piston (floating.py), the gas behind
it.

Sign conventions of the project (DESIGN.md 4): the stroke s grows in
rebound (the rebound chamber shrinks), the rod force is positive in
tension, the rod acceleration is reported positive up.
"""

from __future__ import annotations

from numba import njit

from ..jit import lazy_njit
from ..solver import rhs_signature
from . import aeration as ae
from . import chambers as ch
from . import fixture as fx
from . import floating as fl
from . import freeplay as fp
from . import gas as gs
from . import intake as ik
from . import mount as mt
from . import passive as pv
from . import shims as sh
from . import solenoid as sv
from . import thermal as th
from .fluid import BETA_T, JIT, P_ATM, P_REF, RHO0, density, viscosity
from .layout import (BENCH_BLOCK, BENCH_KIND, BENCH_P, BENCH_V, CURRENT, EX_DT, EX_T0, O_A_ROD, O_DISS, O_DP, O_F_ACT,
                     O_F_MU, O_F_ROD, O_F_TM, O_I, O_LIFT, O_MAG, O_MASS, O_P_B, O_P_C, O_P_K, O_P_R, O_P_RES, O_Q_A,
                     O_Q_BP, O_Q_BV, O_Q_IN, O_Q_P, O_S, O_T_GAS, O_T_OIL, O_U, O_V, O_X_BC, O_X_BI, O_X_M, O_X_P,
                     O_X_PI, O_X_PR, O_X_TM, O_V_GAS, O_X_FP, PO, SO, TO, E_GE, E_TW, E_VS, E_XS, EXT_AT, FP_AT)
from .seal import seal

SIG = rhs_signature()
OIL, CH, GAS = PO["oil"], PO["chambers"], PO["gas"]
PR, BC, PI, BI, AV = (PO["piston_rebound"], PO["base_compression"], PO["piston_intake"], PO["base_intake"],
                      PO["active_valve"])
SEAL, MOUNT, FIX, RUN = PO["seal"], PO["mount"], PO["fixture"], PO["run"]
FP, TH, AE, FL = PO["free_play"], PO["thermal"], PO["aeration"], PO["floating"]
X_DAMPER, X_MODULE = EXT_AT["damper+"], EXT_AT["module+"]
F_DAMPER, F_MODULE = FP_AT["damper_fp"], FP_AT["module_fp"]
S_CH, S_GAS, S_PR, S_BC, S_PI, S_BI, S_AV, S_SEAL, S_FIX, S_ROD, S_MOUNT = (
    SO["chambers"], SO["gas"], SO["piston_rebound"], SO["base_compression"], SO["piston_intake"],
    SO["base_intake"], SO["active_valve"], SO["seal"], SO["fixture"], SO["rod"], SO["mount"])
T_MOUNT, T_FIX = TO["mount"], TO["fixture"]


@njit(**JIT)
def prescribed(t, p, ex):
    """Prescribed input and its rate at t: between two samples the cubic
    Bezier curve through the sample values with the sampled rates as end
    tangents (control points u0 + r0 h/3, u1 - r1 h/3), evaluated by de
    Casteljau's construction: smooth (C1), so the integrator need not stop
    at every sample. Before the record: the first value at rest."""
    h = p[RUN + EX_DT]
    r = (t - p[RUN + EX_T0]) / h
    n = ex.shape[1]
    if r <= 0.0:
        return ex[0, 0], 0.0
    if r >= n - 1:
        return ex[0, n - 1], ex[1, n - 1] if r <= n - 1 + 1e-9 else 0.0
    k = int(r)
    f = r - k
    b0 = ex[0, k]
    b3 = ex[0, k + 1]
    b1 = b0 + ex[1, k] * h / 3.0
    b2 = b3 - ex[1, k + 1] * h / 3.0
    c0 = b0 + f * (b1 - b0)
    c1 = b1 + f * (b2 - b1)
    c2 = b2 + f * (b3 - b2)
    d0 = c0 + f * (c1 - c0)
    d1 = c1 + f * (c2 - c1)
    return d0 + f * (d1 - d0), 3.0 * (d1 - d0) / h


@njit(**JIT)
def _mean(a, b):
    return 0.5 * (a + b)


@njit(**JIT)
def reservoir_displacement(y, p):
    """Volume [m^3] the moving parts displace into the reservoir, and its
    rate [m^3/s]: the base compression stack and the base intake disc, the
    active valve's main stage (its outlet annulus A_K - A_M) and pilot."""
    A_mk = p[AV + sv.A_K] - p[AV + sv.A_M]
    A_pl = sv.pilot_area(p, AV)
    V = (p[BC + sh.A_EQ] * y[S_BC + sh.X] - p[BI + ik.A_P] * y[S_BI + ik.X] - A_mk * y[S_AV + sv.XM]
         + A_pl * y[S_AV + sv.XP])
    dV = (p[BC + sh.A_EQ] * y[S_BC + sh.V] - p[BI + ik.A_P] * y[S_BI + ik.V] - A_mk * y[S_AV + sv.VM]
          + A_pl * y[S_AV + sv.VP])
    return V, dV


@njit(**JIT)
def volumes(y, p, s, sd):
    """Chamber volumes [m^3] at stroke s [m] with the parts' lifts and the
    walls' stretch, and their rates [m^3/s] at stroke rate sd with the
    pressures held: (V_r, dV_r, V_c, dV_c, V_b, dV_b, V_k, dV_k, V_sw, dV_sw,
    W_r, W_c, W_t). Each part sweeps the area its pressures load (virtual
    work: tests/test_truth_physics.py); the pressure tube's wall stretches
    with P_r - P_b and P_c - P_b over the bore lengths (compliance
    W = KAPPA_PT A_B l), the third tube's with P_b - P_W (W_t, the reservoir
    at its rest pressure); V_sw is the volume displaced into the reservoir,
    the third tube's bulge included."""
    A_r, A_b = p[CH + ch.A_R], p[CH + ch.A_B]
    A0, A1, A_m = p[PR + sh.A_EQ], p[PI + ik.A_P], p[AV + sv.A_M]
    x0, x1, v0, v1 = y[S_PR + sh.X], y[S_PI + ik.X], y[S_PR + sh.V], y[S_PI + ik.V]
    P_r, P_c, P_b = y[S_CH + ch.PR], y[S_CH + ch.PC], y[S_CH + ch.PB]
    V_sw, dV_sw = reservoir_displacement(y, p)
    kw = p[CH + ch.KAPPA_PT] * A_b
    l_r, l_c = p[CH + ch.L_R0] - s, p[CH + ch.L_C0] + s
    W_r, W_c, W_t = kw * l_r, kw * l_c, p[CH + ch.KAPPA_TT] * p[CH + ch.V_B]
    stretch_r, stretch_c, bulge = W_r * (P_r - P_b), W_c * (P_c - P_b), W_t * (P_b - p[CH + ch.P_W])
    V_r = A_r * l_r + A0 * x0 - A1 * x1 + stretch_r
    dV_r = -A_r * sd + A0 * v0 - A1 * v1 - kw * sd * (P_r - P_b)
    V_c = (A_b * l_c - A0 * x0 + A1 * x1 + p[BC + sh.A_EQ] * y[S_BC + sh.X] - p[BI + ik.A_P] * y[S_BI + ik.X]
           + stretch_c)
    dV_c = (A_b * sd - A0 * v0 + A1 * v1 + p[BC + sh.A_EQ] * y[S_BC + sh.V] - p[BI + ik.A_P] * y[S_BI + ik.V]
            + kw * sd * (P_c - P_b))
    V_b = p[CH + ch.V_B] + A_m * y[S_AV + sv.XM] - stretch_r - stretch_c + bulge
    dV_b = A_m * y[S_AV + sv.VM] + kw * sd * (P_r - P_b) - kw * sd * (P_c - P_b)
    A_pl = sv.pilot_area(p, AV)
    V_k = p[AV + sv.V_K] - p[AV + sv.A_K] * y[S_AV + sv.XM] + A_pl * y[S_AV + sv.XP]
    dV_k = -p[AV + sv.A_K] * y[S_AV + sv.VM] + A_pl * y[S_AV + sv.VP]
    return V_r, dV_r, V_c, dV_c, V_b, dV_b, V_k, dV_k, V_sw + bulge, dV_sw, W_r, W_c, W_t


@njit(**JIT)
def _damper(t, y, p, ex, dy, out, module, ext, fpo):
    """The damper (module False) or the module; ``ext`` >= 0: the start of
    the hidden effects' states (layout.EXT_BLOCKS), -1: none (their effects off);
    ``fpo`` >= 0: the start of a mono tube's floating-piston states, -1: none."""
    for k in range(out.shape[0]):
        out[k] = 0.0
    if ext >= 0:  # the extension's states whose effect is off (or absent, as the play in the damper test) rest
        for k in range(ext, dy.shape[0]):
            dy[k] = 0.0
    u, du = prescribed(t, p, ex)
    if module:
        x_top, v_top = y[S_ROD], y[S_ROD + 1]
    else:
        x_top, v_top = y[S_FIX + fx.XF], y[S_FIX + fx.VF]
    s = u - x_top
    sd = du - v_top
    T = y[S_CH + ch.T_OIL]
    P_r, P_c, P_b = y[S_CH + ch.PR], y[S_CH + ch.PC], y[S_CH + ch.PB]
    mu = viscosity(T, p, OIL) * p[OIL + RHO0]
    triple = p[CH + ch.ARCH] < 0.5
    mono = p[CH + ch.ARCH] > 1.5
    # reserve
    rho_ref = density(p[OIL + P_REF], T, p, OIL)
    V_oil = y[S_GAS + gs.M_RES] / rho_ref
    if triple:
        V_r, dV_r, V_c, dV_c, V_b, dV_b, V_k, dV_k, V_sw, dV_sw, W_r, W_c, W_t = volumes(y, p, s, sd)
    else:  # the pressure tube in the reserve at its rest pressure (twin) or in the air (mono)
        P_out = p[OIL + P_ATM] if mono else p[CH + ch.P_W]
        V_r, dV_r, V_c, dV_c, V_sw, dV_sw, W_r, W_c = pv.volumes(y, p, s, sd, mono, fpo, P_out)
        V_b, dV_b, V_k, dV_k, W_t = 0.0, 0.0, 0.0, 0.0, 0.0
    P_res, V_g = gs.reserve_pressure(y, S_GAS, p, GAS, V_oil, V_sw)
    P_k = y[S_AV + sv.PK]
    rho_r, rho_c, rho_b = density(P_r, T, p, OIL), density(P_c, T, p, OIL), density(P_b, T, p, OIL)
    rho_s, rho_k = density(P_res, T, p, OIL), density(P_k, T, p, OIL)
    # valves and passages
    Q0, Qb0, _, L0 = sh.shim_valve(y, S_PR, p, PR, P_r, P_c, _mean(rho_r, rho_c), mu, dy)
    Q1, _, L1 = ik.intake_valve(y, S_PI, p, PI, P_c, P_r, _mean(rho_r, rho_c), mu, dy)
    if mono:  # no base valves
        Q2, Qb2, L2, Q3, L3 = 0.0, 0.0, 0.0, 0.0, 0.0
        pv.rest(dy, S_BC, S_BC + len(sh.STATES))
        pv.rest(dy, S_BI, S_BI + len(ik.STATES))
    else:
        Q2, Qb2, _, L2 = sh.shim_valve(y, S_BC, p, BC, P_c, P_res, _mean(rho_c, rho_s), mu, dy)
        Q3, _, L3 = ik.intake_valve(y, S_BI, p, BI, P_res, P_c, _mean(rho_c, rho_s), mu, dy)
    Q_lk, F_band, L_lk = ch.band_leakage(P_r - P_c, sd, mu, p, CH)
    if triple:
        Q_bp = ch.bypass(P_r - P_b, mu, _mean(rho_r, rho_b), p, CH)
        Q_a, Q_f, Q_pl, P_mag, L_av = sv.active_valve(y, S_AV, p, AV, p[RUN + CURRENT], P_b, P_res, rho_b, mu, dy)
    else:  # no third tube, no active valve: their states rest
        Q_bp, Q_a, Q_f, Q_pl, P_mag, L_av = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        pv.rest(dy, S_AV, S_AV + len(sv.STATES))
    F_fp, L_fp = 0.0, 0.0
    if mono:  # the floating piston between the compression oil and the gas (P_res: the gas chamber's)
        F_fp, L_fp = fl.floating_piston(y, fpo, p, FL, P_c, P_res, p[CH + ch.A_B], dy)
    F_seal, L_seal = seal(y, S_SEAL, p, SEAL, sd, P_r - p[OIL + P_ATM], dy)
    F_d = (P_r - p[OIL + P_ATM]) * p[CH + ch.A_R] - (P_c - p[OIL + P_ATM]) * p[CH + ch.A_B] + F_seal + F_band
    # top: fixture (damper) or rod, mount and fixture (module)
    a_rod = 0.0
    F_tm = 0.0
    L_top = 0.0
    if module and ext >= 0 and p[FP + fp.ON] > 0.5:  # the rod in the play, the sleeve on the rubber
        x_s, v_s = y[ext + E_XS], y[ext + E_VS]
        F_c, L_c = fp.contact(x_top - x_s, v_top - v_s, p, FP)
        F_tm, L_m = mt.mount(y, S_MOUNT, p, MOUNT, x_s - y[S_FIX + fx.XF], v_s - y[S_FIX + fx.VF], dy)
        a_rod = (F_d - F_c) / p[CH + ch.M_ROD]
        dy[S_ROD] = v_top
        dy[S_ROD + 1] = a_rod
        dy[ext + E_XS] = v_s
        dy[ext + E_VS] = (F_c - F_tm) / p[FP + fp.M_S]
        F_lc, L_f = fx.fixture(y, S_FIX, p, FIX, F_tm, dy)
        L_top = L_m + L_f + L_c
    elif module:
        F_tm, L_m = mt.mount(y, S_MOUNT, p, MOUNT, x_top - y[S_FIX + fx.XF], v_top - y[S_FIX + fx.VF], dy)
        a_rod = (F_d - F_tm) / p[CH + ch.M_ROD]
        dy[S_ROD] = v_top
        dy[S_ROD + 1] = a_rod
        F_lc, L_f = fx.fixture(y, S_FIX, p, FIX, F_tm, dy)
        L_top = L_m + L_f
    else:
        F_lc, L_top = fx.fixture(y, S_FIX, p, FIX, F_d, dy)
    # mass flows (mean density of the two ends: what leaves one chamber enters the other)
    m_p = _mean(rho_r, rho_c) * (Q0 + Qb0 + Q_lk - Q1)
    m_bv = _mean(rho_c, rho_s) * (Q2 + Qb2 - Q3)
    m_bp = _mean(rho_r, rho_b) * Q_bp
    m_a = _mean(rho_b, rho_s) * Q_a
    m_f = _mean(rho_b, rho_k) * Q_f
    m_pl = _mean(rho_k, rho_s) * Q_pl
    # oil temperature (the gas heat enters with the gas temperature difference of the state)
    loss = (L0 + L1 + L2 + L3 + L_lk + (P_r - P_b) * Q_bp + L_av + L_seal + L_top)
    if mono:
        loss += L_fp
    q_gas = 0.0
    if p[GAS + gs.HEAT] > 0.5:
        q_gas = p[GAS + gs.H] * (y[S_GAS + gs.T_G] - T)
    # the rubber's and the fixture's losses heat them, not the oil
    if ext >= 0 and p[TH + th.ON] > 0.5:  # two nodes: oil and the tubes' steel (two_node_thermal)
        dT, dT_w = 0.0, 0.0
        if p[CH + ch.THERMAL] > 0.5:
            dT, dT_w = th.two_node(T, y[ext + E_TW], loss - L_top + q_gas, p[CH + ch.HA], p[CH + ch.T_AMB], p, TH)
        dy[ext + E_TW] = dT_w
    else:
        dT = ch.oil_heating(T, loss - L_top + q_gas, p, CH)
    # chambers: free gas, then the mass balances coupled through the walls
    g_r, g_c, g_b = y[S_CH + ch.GR], y[S_CH + ch.GC], y[S_CH + ch.GB]
    P_ref = p[OIL + P_REF]
    # entrained reserve gas in the compression chamber (air_entrainment): its rate [m^3/s at P_ref] and the
    # gas mass it takes from the reserve [kg/s] (at the run's reference temperature, as g is counted)
    g_e, dg_e, m_e = 0.0, 0.0, 0.0
    if ext >= 0 and p[AE + ae.ON] > 0.5:
        g_e = y[ext + E_GE]
        e_in, e_out = ae.entrainment(g_e, Q3, P_res, P_ref, p, AE)
        dg_e = e_in - e_out
        m_e = dg_e * P_ref / (p[GAS + gs.R_S] * p[CH + ch.T_AMB])
        dy[ext + E_GE] = dg_e
    g_ct = g_c + g_e  # the compression chamber's free gas: dissolved-air bubbles and entrained gas
    dg_r = gs.free_gas_rate(g_r, P_r, ch.liquid_volume(P_r, V_r, g_r, p, OIL), P_ref, p, GAS)
    dg_c = gs.free_gas_rate(g_c, P_c, ch.liquid_volume(P_c, V_c, g_ct, p, OIL), P_ref, p, GAS)
    dg_b = 0.0
    if triple:
        dg_b = gs.free_gas_rate(g_b, P_b, ch.liquid_volume(P_b, V_b, g_b, p, OIL), P_ref, p, GAS)
    dy[S_CH + ch.GR], dy[S_CH + ch.GC], dy[S_CH + ch.GB] = dg_r, dg_c, dg_b
    a_r, b_r = ch.balance(P_r, T, dT, V_r, dV_r, g_r, dg_r, -m_p - m_bp, p, OIL)
    a_c, b_c = ch.balance(P_c, T, dT, V_c, dV_c, g_ct, dg_c + dg_e, m_p - m_bv, p, OIL)
    if triple:
        a_b, b_b = ch.balance(P_b, T, dT, V_b, dV_b, g_b, dg_b, m_bp - m_a - m_f, p, OIL)
        dP_r, dP_c, dP_b = ch.walled_rates(a_r, b_r, a_c, b_c, a_b, b_b, W_r, W_c, W_t)
        dy[S_AV + sv.PK] = ch.pressure_rate(P_k, T, dT, V_k, dV_k, 0.0, 0.0, m_f - m_pl, p, OIL)
    else:  # the pressure tube's wall against a constant outside pressure: (a + W) dP = b
        dP_r, dP_c, dP_b = b_r / (a_r + W_r), b_c / (a_c + W_c), 0.0
    dy[S_CH + ch.PR], dy[S_CH + ch.PC], dy[S_CH + ch.PB] = dP_r, dP_c, dP_b
    # reserve: oil in, parts and the third tube's wall displacing, oil expanding (mono: the floating piston
    # displacing the gas, no oil beside it)
    dV_oil_mass = (m_bv + m_a + m_pl) / rho_ref
    dV_g = -(dV_oil_mass + p[OIL + BETA_T] * V_oil * dT + dV_sw + W_t * dP_b)
    if not triple and not mono:  # the twin tube's pressure tube stretching into the reserve
        dV_g -= W_r * dP_r + W_c * dP_c
    gs.reserve(y, S_GAS, p, GAS, P_res, V_g, dV_g, V_oil, T, dy)
    if m_e != 0.0:  # the gas leaving the reserve takes its enthalpy (open system, as gas.reserve's dissolution)
        dy[S_GAS + gs.M_G] -= m_e
        dy[S_GAS + gs.T_G] -= p[GAS + gs.R_S] * y[S_GAS + gs.T_G] * m_e / (y[S_GAS + gs.M_G] * p[GAS + gs.C_V])
    dy[S_GAS + gs.M_RES] = m_bv + m_a + m_pl
    dy[S_CH + ch.T_OIL] = dT
    out[O_U] = u
    out[O_V] = du
    out[O_S] = s
    out[O_F_ACT] = F_d
    out[O_F_MU] = F_seal
    if module:
        out[O_F_ROD] = F_d
        out[O_F_TM] = F_lc
        out[O_A_ROD] = -a_rod
        out[O_X_TM] = x_top - y[S_FIX + fx.XF]  # the rod against the top-mount housing (module LVDT)
    else:
        out[O_F_ROD] = F_lc
    out[O_P_R], out[O_P_C], out[O_P_B], out[O_P_RES], out[O_P_K] = P_r, P_c, P_b, P_res, P_k
    out[O_V_GAS] = V_g
    if not triple:  # no third tube, no active valve's control chamber
        out[O_P_B], out[O_P_K] = 0.0, 0.0
    if mono:
        out[O_X_FP] = y[fpo + fl.X]
    out[O_X_PR], out[O_X_PI] = y[S_PR + sh.X], y[S_PI + ik.X]
    out[O_X_BC], out[O_X_BI] = y[S_BC + sh.X], y[S_BI + ik.X]
    out[O_X_M], out[O_X_P] = y[S_AV + sv.XM], y[S_AV + sv.XP]
    out[O_Q_P] = Q0 + Qb0 + Q_lk - Q1
    out[O_Q_BV] = Q2 + Qb2 - Q3
    out[O_Q_BP] = Q_bp
    out[O_Q_A] = Q_a + Q_pl
    out[O_I] = sv.coil_current(y[S_AV + sv.I], p[RUN + CURRENT], p, AV)
    out[O_T_OIL] = T
    out[O_T_GAS] = y[S_GAS + gs.T_G]
    if triple:
        out[O_MASS] = (ch.oil_mass(P_r, T, V_r, g_r, p, OIL) + ch.oil_mass(P_c, T, V_c, g_ct, p, OIL)
                       + ch.oil_mass(P_b, T, V_b, g_b, p, OIL) + ch.oil_mass(P_k, T, V_k, 0.0, p, OIL)
                       + y[S_GAS + gs.M_RES])
    else:
        out[O_MASS] = (ch.oil_mass(P_r, T, V_r, g_r, p, OIL) + ch.oil_mass(P_c, T, V_c, g_ct, p, OIL)
                       + y[S_GAS + gs.M_RES])
    out[O_DISS] = loss + q_gas
    out[O_MAG] = P_mag


@lazy_njit(SIG, **JIT)
def rhs_damper(t, y, p, ex, aux, dy, out):
    """Damper test: tube displacement prescribed, rod on the crosshead."""
    _damper(t, y, p, ex, dy, out, False, -1, -1)


@lazy_njit(SIG, **JIT)
def rhs_damper_ext(t, y, p, ex, aux, dy, out):
    """Damper test with the hidden effects' states (layout.EXT_BLOCKS)."""
    _damper(t, y, p, ex, dy, out, False, X_DAMPER, -1)


@lazy_njit(SIG, **JIT)
def rhs_module(t, y, p, ex, aux, dy, out):
    """Module test: the rod on the top mount, the mount on the crosshead."""
    _damper(t, y, p, ex, dy, out, True, -1, -1)


@lazy_njit(SIG, **JIT)
def rhs_module_ext(t, y, p, ex, aux, dy, out):
    """Module test with the hidden effects' states (layout.EXT_BLOCKS)."""
    _damper(t, y, p, ex, dy, out, True, X_MODULE, -1)


@lazy_njit(SIG, **JIT)
def rhs_damper_fp(t, y, p, ex, aux, dy, out):
    """Damper test of a mono tube (its floating piston after the extension's states)."""
    _damper(t, y, p, ex, dy, out, False, X_DAMPER, F_DAMPER)


@lazy_njit(SIG, **JIT)
def rhs_module_fp(t, y, p, ex, aux, dy, out):
    """Module test of a mono tube (its floating piston after the extension's states)."""
    _damper(t, y, p, ex, dy, out, True, X_MODULE, F_MODULE)


@lazy_njit(SIG, **JIT)
def rhs_topmount(t, y, p, ex, aux, dy, out):
    """Top-mount bench: deflection prescribed at the base, mount on the crosshead."""
    for k in range(out.shape[0]):
        out[k] = 0.0
    X, Xd = prescribed(t, p, ex)
    F_tm, L_m = mt.mount(y, T_MOUNT, p, MOUNT, X - y[T_FIX + fx.XF], Xd - y[T_FIX + fx.VF], dy)
    F_lc, L_f = fx.fixture(y, T_FIX, p, FIX, F_tm, dy)
    out[O_U] = X
    out[O_V] = Xd
    out[O_F_TM] = F_lc
    out[O_DISS] = L_m + L_f


@lazy_njit(SIG, **JIT)
def rhs_valve(t, y, p, ex, aux, dy, out):
    """Flow bench: a prescribed flow into an upstream volume of degassed oil,
    one passive valve to a constant back pressure."""
    for k in range(out.shape[0]):
        out[k] = 0.0
    Q_in, dQ = prescribed(t, p, ex)
    P_up = y[0]
    T = p[CH + ch.T_AMB]
    o = int(p[RUN + BENCH_BLOCK])
    P_dn = p[RUN + BENCH_P]
    rho = density(P_up, T, p, OIL)
    mu = viscosity(T, p, OIL) * p[OIL + RHO0]
    if p[RUN + BENCH_KIND] < 0.5:
        Q, Qb, A, L = sh.shim_valve(y, 1, p, o, P_up, P_dn, rho, mu, dy)
        Q = Q + Qb
    else:
        Q, A, L = ik.intake_valve(y, 1, p, o, P_up, P_dn, rho, mu, dy)
        dy[3] = 0.0
    V = p[RUN + BENCH_V] + A * y[1]
    dy[0] = ch.pressure_rate(P_up, T, 0.0, V, A * y[2], 0.0, 0.0, rho * (Q_in - Q), p, OIL)
    out[O_Q_IN] = Q_in
    out[O_DP] = P_up - P_dn
    out[O_LIFT] = y[1]
    out[O_P_R] = P_up
    out[O_Q_P] = Q
    out[O_DISS] = L


@lazy_njit(SIG, **JIT)
def rhs_active_valve(t, y, p, ex, aux, dy, out):
    """The active valve alone on a pressure bench: prescribed pressure drop
    (ex) over it, outlet at the bench's back pressure, degassed oil."""
    for k in range(out.shape[0]):
        out[k] = 0.0
    dp, _ = prescribed(t, p, ex)
    P_out = p[RUN + BENCH_P]
    P_in = P_out + dp
    T = p[CH + ch.T_AMB]
    rho = density(P_in, T, p, OIL)
    mu = viscosity(T, p, OIL) * p[OIL + RHO0]
    Q_a, Q_f, Q_pl, P_mag, L_av = sv.active_valve(y, 0, p, AV, p[RUN + CURRENT], P_in, P_out, rho, mu, dy)
    P_k = y[sv.PK]
    rho_k = density(P_k, T, p, OIL)
    A_pl = sv.pilot_area(p, AV)
    V_k = p[AV + sv.V_K] - p[AV + sv.A_K] * y[sv.XM] + A_pl * y[sv.XP]
    dV_k = -p[AV + sv.A_K] * y[sv.VM] + A_pl * y[sv.VP]
    dy[sv.PK] = ch.pressure_rate(P_k, T, 0.0, V_k, dV_k, 0.0, 0.0,
                                 _mean(rho, rho_k) * Q_f - _mean(rho_k, rho) * Q_pl, p, OIL)
    out[O_DP] = dp
    out[O_Q_IN] = Q_a + Q_pl
    out[O_P_K] = P_k
    out[O_X_M] = y[sv.XM]


RHS = {"valve": rhs_valve, "damper": rhs_damper, "module": rhs_module, "topmount": rhs_topmount,
       "active_valve": rhs_active_valve, "damper+": rhs_damper_ext, "module+": rhs_module_ext,
       "damper_fp": rhs_damper_fp, "module_fp": rhs_module_fp}
