"""Index layout of the compiled model's parameter vector and state vectors.

The compiled functions read these module constants at compile time: after
editing this file, clear numba's cache (``find src -name '*.nbi' -delete``)
so cached functions in other modules recompile.
"""

from .valves import V_SIZE

_names = """
A_R A_B L_R0 L_C0 V_B M_ROD
K_OIL RHO NU P_SAT P_VAP CHI GAMMA P0 TEMP
PSI_PT PSI_TT RATIO_TT
P_ATM P_REF T_REF RHO_GAS V_G0 A_BP CQ_BP P_TR ZETA K_C ZETA_C DELTA_C G_LEAK
FR_FC FR_FS FR_KB FR_S2 FR_CCOMP FR_VD FR_AS FR_ALPHAS
TM_R TM_P0 TM_P1 TM_P2 TM_Q0 TM_Q1 TM_Q2 TM_K0 TM_K1 TM_K2 TM_C0 TM_C1 TM_C2 TM_YU TM_WU
TM_FLD0 TM_FLD1 TM_FLD2 TM_FLD3 TM_FLD4
CURRENT
E_GAS E_WALL E_CAV E_STICTION E_SHIM_FRICTION E_JET E_CQ E_SLOT E_ROD_FRICTION E_TM_DYNAMICS E_LEAK
BENCH_V BENCH_P_DOWN BENCH_VALVE
EX_T0 EX_DT
""".split()
for _i, _n in enumerate(_names):
    globals()["P_" + _n] = _i
P_VALVES = len(_names)  # four valve blocks follow, V_SIZE each
N_FLD = 5
N_PARAMS = P_VALVES + 4 * V_SIZE
PARAM_NAMES = tuple(_names) + tuple(f"valve{k}.{j}" for k in range(4) for j in range(V_SIZE))

# Valve order (block k at P_VALVES + k*V_SIZE)
VALVE_NAMES = ("piston_rebound", "piston_intake", "base_compression", "base_intake")

# ---- configurations
CFG_VALVE, CFG_DAMPER, CFG_MODULE = 0, 1, 2
CFG_SOLVER_TEST = 3  # analytic test problem for the integrator (3 states)
CFG_TOPMOUNT = 4  # the top mount alone, deflection X(t) prescribed (3 states)
CONFIGURATIONS = {"valve": CFG_VALVE, "damper": CFG_DAMPER, "module": CFG_MODULE, "topmount": CFG_TOPMOUNT}

# ---- state layout, damper / module configuration
S_PR, S_PC, S_PB, S_VG = 0, 1, 2, 3
S_X0 = 4  # valve k: lift at S_X0 + 2k, velocity at S_X0 + 2k + 1
S_DAHL_PR, S_DAHL_BC = 12, 13  # Dahl force of the two shim stacks
S_Z = 14  # LuGre bristle deflection
N_DAMPER = 15
S_XROD, S_VROD, S_TMX, S_TMY, S_TMW = 15, 16, 17, 18, 19
N_MODULE = 20

# ---- state layout, flow-bench (valve) configuration
B_P, B_X, B_V, B_F = 0, 1, 2, 3
N_VALVE = 4

# ---- state layout, top mount alone
T_X, T_Y, T_W = 0, 1, 2

N_STATES = {CFG_VALVE: N_VALVE, CFG_DAMPER: N_DAMPER, CFG_MODULE: N_MODULE, CFG_SOLVER_TEST: 3, CFG_TOPMOUNT: 3}

# ---- output channels computed at every output time
OUTPUTS = (
    ("displacement [m]", "u"), ("velocity [m/s]", "v"), ("stroke [m]", "s"),
    ("rod force [N]", "F_d"), ("top mount force [N]", "F_tm"), ("rod acceleration [m/s^2]", "a_rod"),
    ("friction force [N]", "F_mu"),
    ("p rebound [Pa]", "P_r"), ("p compression [Pa]", "P_c"), ("p third tube [Pa]", "P_b"),
    ("p reserve [Pa]", "P_res"),
    ("lift piston_rebound [m]", "x0"), ("lift piston_intake [m]", "x1"),
    ("lift base_compression [m]", "x2"), ("lift base_intake [m]", "x3"),
    ("flow piston_rebound [m^3/s]", "Q0"), ("flow piston_intake [m^3/s]", "Q1"),
    ("flow base_compression [m^3/s]", "Q2"), ("flow base_intake [m^3/s]", "Q3"),
    ("flow bypass [m^3/s]", "Q_bp"), ("flow active valve [m^3/s]", "Q_a"),
    ("storage rebound [m^3/s]", "St_r"), ("storage compression [m^3/s]", "St_c"),
    ("storage third tube [m^3/s]", "St_b"), ("gas volume rate [m^3/s]", "dVg"),
)
for _i, (_c, _n) in enumerate(OUTPUTS):
    globals()["O_" + _n.upper()] = _i
N_OUT = len(OUTPUTS)
