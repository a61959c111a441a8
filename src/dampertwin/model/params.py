"""From a Design to the compiled model's parameter vector, initial state and
state scales. Pure functions, no I/O."""

from __future__ import annotations

import math

import numpy as np

from ..design import Design
from . import layout as L
from .fluid import wall_compliance
from .valves import (
    V_A, V_AB, V_ALPHA, V_B, V_C, V_CC, V_CQ, V_CQB, V_CQS, V_D, V_DD, V_DH, V_DI, V_FC, V_LAM,
    V_M, V_PRE, V_SHIM, V_SIG, V_SIZE, V_XMAX, V_XV0, V_AS, stiffness_force,
)

EFFECT_INDEX = {
    "gas_content": L.P_E_GAS,
    "wall_compliance": L.P_E_WALL,
    "cavitation": L.P_E_CAV,
    "valve_stiction": L.P_E_STICTION,
    "shim_friction": L.P_E_SHIM_FRICTION,
    "jet_force": L.P_E_JET,
    "flow_number_cq": L.P_E_CQ,
    "slot_restriction": L.P_E_SLOT,
    "rod_friction": L.P_E_ROD_FRICTION,
    "top_mount_dynamics": L.P_E_TM_DYNAMICS,
    "piston_leakage": L.P_E_LEAK,
}

# Flow-bench defaults (THESIS-ERRATA 37): 0.2 L upstream, 2 bar back pressure (gauge)
BENCH_VOLUME = 2.0e-4  # [m^3]
BENCH_BACK_PRESSURE = 2.0e5 + 101325.0  # [Pa abs]


def pack(design: Design, current: float = 1.6, effects: dict | None = None,
         bench_valve: str | None = None, bench_volume: float = BENCH_VOLUME,
         bench_back_pressure: float = BENCH_BACK_PRESSURE) -> np.ndarray:
    """Parameter vector of the compiled model (layout.P_*), SI units.

    ``current`` is the active-valve current [A] (a test condition);
    ``effects`` overrides the design's effect switches."""
    d = design
    p = np.zeros(L.N_PARAMS)
    g = d.group("geometry")
    D_PT, D_R = g["D_PT"], g["D_R"]
    p[L.P_A_R] = math.pi * (D_PT**2 - D_R**2) / 4.0  # eq. 4.2 (annulus)
    p[L.P_A_B] = math.pi * D_PT**2 / 4.0  # eq. 4.3
    p[L.P_L_R0], p[L.P_L_C0], p[L.P_V_B], p[L.P_M_ROD] = g["l_r0"], g["l_c0"], g["V_b"], g["M_rod"]
    o = d.group("oil")
    p[L.P_K_OIL], p[L.P_RHO], p[L.P_NU] = o["K_oil"], o["rho_oil"], o["nu"]
    p[L.P_P_SAT], p[L.P_P_VAP], p[L.P_CHI], p[L.P_GAMMA] = o["P_sat"], o["P_vap"], o["chi"], o["Gamma"]
    p[L.P_P0], p[L.P_TEMP] = o["P_0"], o["T"]
    tt = d.group("third_tube")
    c = d.constant
    p[L.P_PSI_TT] = wall_compliance(tt["E"], tt["nu_p"], tt["r_i"], tt["r_o"])  # eq. 4.17
    p[L.P_PSI_PT] = wall_compliance(tt["E"], tt["nu_p"], c("pt_r_i"), c("pt_r_o"))
    p[L.P_RATIO_TT] = c("wall_ratio_third_tube")
    for name, idx in [("P_atm", L.P_P_ATM), ("P_ref", L.P_P_REF), ("T_ref", L.P_T_REF),
                      ("rho_gas", L.P_RHO_GAS), ("V_gas0", L.P_V_G0), ("A_bypass", L.P_A_BP),
                      ("Cq_bypass", L.P_CQ_BP), ("p_transition", L.P_P_TR), ("zeta", L.P_ZETA),
                      ("k_contact", L.P_K_C), ("zeta_contact", L.P_ZETA_C), ("delta_contact", L.P_DELTA_C),
                      ("s2", L.P_FR_S2), ("c_comp", L.P_FR_CCOMP), ("vd", L.P_FR_VD), ("a_s", L.P_FR_AS),
                      ("alpha_s", L.P_FR_ALPHAS), ("y_unit", L.P_TM_YU), ("w_unit", L.P_TM_WU)]:
        p[idx] = c(name)
    # laminar annular-gap conductance of the piston band: pi D h^3 / (12 mu L) [m^3/(s Pa)]
    mu = o["rho_oil"] * o["nu"]
    p[L.P_G_LEAK] = math.pi * D_PT * c("leak_gap") ** 3 / (12.0 * mu * c("leak_length"))
    f = d.group("rod_friction")
    p[L.P_FR_FC], p[L.P_FR_FS], p[L.P_FR_KB] = f["F_c"], f["F_s"], f["k_b"]
    tm = d.group("top_mount")
    for name in ("R", "p0", "p1", "p2", "q0", "q1", "q2", "k0", "k1", "k2", "c0", "c1", "c2"):
        p[getattr(L, "P_TM_" + name.upper())] = tm[name]
    fld = tm["F_LD"]
    if len(fld) > L.N_FLD:
        raise ValueError(f"design {d.name!r}: top_mount.F_LD has {len(fld)} coefficients; at most {L.N_FLD} supported")
    p[L.P_TM_FLD0:L.P_TM_FLD0 + len(fld)] = fld
    p[L.P_CURRENT] = current
    eff = dict(d.effects)
    if effects:
        unknown = set(effects) - set(EFFECT_INDEX)
        if unknown:
            raise ValueError(f"unknown effect switch(es) {sorted(unknown)}; expected {sorted(EFFECT_INDEX)}")
        eff.update(effects)
    for name, idx in EFFECT_INDEX.items():
        p[idx] = 1.0 if eff[name] else 0.0
    for k, vname in enumerate(L.VALVE_NAMES):
        _pack_valve(p, L.P_VALVES + k * V_SIZE, d.group(vname), c("x_max_" + vname))
    p[L.P_BENCH_V] = bench_volume
    p[L.P_BENCH_P_DOWN] = bench_back_pressure
    p[L.P_BENCH_VALVE] = L.VALVE_NAMES.index(bench_valve) if bench_valve else 0
    return p


def _pack_valve(p, o, v, x_max):
    shim = "A_bleed" in v
    p[o + V_DD], p[o + V_DI] = v["D_d"], v["D_i"]
    p[o + V_DH] = v.get("D_h", 0.0)
    p[o + V_CQ], p[o + V_LAM] = v["Cq_max"], v["lambda_crit"]
    p[o + V_AB], p[o + V_CQB] = v.get("A_bleed", 0.0), v.get("Cq_bleed", 0.0)
    p[o + V_AS], p[o + V_CQS] = v["A_slot"], v["Cq_slot"]
    p[o + V_M], p[o + V_C] = v["m_v"], v["c_v"]
    p[o + V_SIG], p[o + V_FC], p[o + V_ALPHA] = v.get("sigma0", 0.0), v.get("F_c", 1.0), v.get("alpha", 1.0)
    p[o + V_PRE], p[o + V_A], p[o + V_B], p[o + V_CC], p[o + V_D] = v["F_preload"], v["a"], v["b"], v["c"], v["d"]
    p[o + V_XV0] = v.get("x_v0", 1.0)
    p[o + V_XMAX] = x_max
    p[o + V_SHIM] = 1.0 if shim else 0.0


def seated_lift(p: np.ndarray, k: int) -> float:
    """Lift [m] where valve k rests on its seat with no pressure difference:
    the seat contact balances the preloaded spring (x < 0)."""
    o = L.P_VALVES + k * V_SIZE
    k_c = p[L.P_K_C]
    x = -p[o + V_PRE] / k_c
    for _ in range(50):  # Newton on k_c(-x) - F_k(x) = 0
        r = -k_c * x - stiffness_force(x, p[o + V_PRE], p[o + V_A], p[o + V_B], p[o + V_CC], p[o + V_D])
        dk = p[o + V_A] * p[o + V_B] * math.exp(p[o + V_B] * x) + p[o + V_CC] * p[o + V_D] * math.exp(p[o + V_D] * x)
        step = r / (-k_c - dk)
        x -= step
        if abs(step) < 1e-16:
            break
    return x


def static_rod_offset(p: np.ndarray) -> float:
    """Top-mount deflection [m] balancing the static gas force on the rod:
    F_LD(X) = (P0 - P_atm)(A_r - A_b) (THESIS-ERRATA 5)."""
    F0 = (p[L.P_P0] - p[L.P_P_ATM]) * (p[L.P_A_R] - p[L.P_A_B])
    coef = p[L.P_TM_FLD0:L.P_TM_FLD0 + L.N_FLD]
    X = F0 / coef[0]
    for _ in range(60):
        F = sum(coef[k] * X ** (k + 1) for k in range(L.N_FLD))
        dF = sum((k + 1) * coef[k] * X**k for k in range(L.N_FLD))
        step = (F - F0) / dF
        X -= step
        if abs(step) < 1e-15:
            break
    return X


def initial_state(p: np.ndarray, cfg: int, u0: float = 0.0) -> np.ndarray:
    """Rest state: every chamber at the precharge pressure, valves seated at
    equilibrium, friction states zero, top mount in static equilibrium."""
    n = L.N_STATES[cfg]
    y = np.zeros(n)
    if cfg in (L.CFG_TOPMOUNT, L.CFG_SOLVER_TEST):
        return y
    if cfg == L.CFG_VALVE:
        y[L.B_P] = p[L.P_BENCH_P_DOWN]
        y[L.B_X] = seated_lift(p, int(p[L.P_BENCH_VALVE]))
        return y
    y[L.S_PR] = y[L.S_PC] = y[L.S_PB] = p[L.P_P0]
    y[L.S_VG] = p[L.P_V_G0]
    for k in range(4):
        y[L.S_X0 + 2 * k] = seated_lift(p, k)
    if cfg == L.CFG_MODULE:
        y[L.S_XROD] = static_rod_offset(p)
    return y


def state_scales(cfg: int) -> np.ndarray:
    """Typical magnitudes of the states (bar, mm, cm^3, ...) used to scale the
    integrator's variables and error norm."""
    if cfg == L.CFG_VALVE:
        return np.array([1e5, 1e-4, 1e-1, 1.0])
    if cfg == L.CFG_SOLVER_TEST:
        return np.ones(3)
    if cfg == L.CFG_TOPMOUNT:
        return np.full(3, 1e-4)
    s = np.empty(L.N_STATES[cfg])
    s[L.S_PR] = s[L.S_PC] = s[L.S_PB] = 1e5  # bar
    s[L.S_VG] = 1e-5  # 10 cm^3
    for k in range(4):
        s[L.S_X0 + 2 * k] = 1e-4  # 0.1 mm
        s[L.S_X0 + 2 * k + 1] = 1.0  # m/s
    s[L.S_DAHL_PR] = s[L.S_DAHL_BC] = 1.0  # N
    s[L.S_Z] = 1e-5  # 10 um
    if cfg == L.CFG_MODULE:
        s[L.S_XROD] = 1e-4
        s[L.S_VROD] = 1e-2
        s[L.S_TMX] = s[L.S_TMY] = s[L.S_TMW] = 1e-4
    return s
