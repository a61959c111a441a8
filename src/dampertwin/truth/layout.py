"""Vectors of the truth: parameter blocks and state blocks per
configuration, assembled from the submodels' declarations (PARAMS, STATES
beside their equations). Offsets are plain ints, compile-time constants
inside the compiled right-hand sides."""

from __future__ import annotations

import numpy as np

from . import aeration, chambers, fixture, floating, fluid, freeplay, gas, intake, mount, seal, shims, solenoid, thermal

RUN_PARAMS = ("CURRENT", "EX_T0", "EX_DT", "BENCH_V", "BENCH_P", "BENCH_BLOCK", "BENCH_KIND")
CURRENT, EX_T0, EX_DT, BENCH_V, BENCH_P, BENCH_BLOCK, BENCH_KIND = range(len(RUN_PARAMS))
PARAM_BLOCKS = (("oil", fluid.PARAMS), ("chambers", chambers.PARAMS), ("gas", gas.PARAMS),
                ("piston_rebound", shims.PARAMS), ("base_compression", shims.PARAMS),
                ("piston_intake", intake.PARAMS), ("base_intake", intake.PARAMS), ("active_valve", solenoid.PARAMS),
                ("seal", seal.PARAMS), ("mount", mount.PARAMS), ("fixture", fixture.PARAMS),
                ("free_play", freeplay.PARAMS), ("thermal", thermal.PARAMS), ("aeration", aeration.PARAMS),
                ("floating", floating.PARAMS), ("run", RUN_PARAMS))


def _offsets(blocks):
    off, i = {}, 0
    for name, items in blocks:
        off[name] = i
        i += len(items)
    return off, i


PO, N_PARAMS = _offsets(PARAM_BLOCKS)
PARAM_NAMES = tuple(f"{b}.{n}" for b, items in PARAM_BLOCKS for n in items)

ROD_STATES = (("x_rod", "m", 1e-4, "rod displacement"), ("v_rod", "m/s", 0.1, "rod velocity"))
BENCH_STATES = (("P_up", "Pa", 1e5, "flow bench upstream pressure"), *shims.STATES)
DAMPER_BLOCKS = (("chambers", chambers.STATES), ("gas", gas.STATES), ("piston_rebound", shims.STATES),
                 ("base_compression", shims.STATES), ("piston_intake", intake.STATES),
                 ("base_intake", intake.STATES), ("active_valve", solenoid.STATES), ("seal", seal.STATES),
                 ("fixture", fixture.STATES))
MODULE_BLOCKS = DAMPER_BLOCKS + (("rod", ROD_STATES), ("mount", mount.STATES))
TOPMOUNT_BLOCKS = (("mount", mount.STATES), ("fixture", fixture.STATES))
VALVE_BLOCKS = (("bench", BENCH_STATES),)
ACTIVE_BLOCKS = (("active_valve", solenoid.STATES),)
# the states of the effects that are off unless a sample names them, appended to the damper's / module's
# (configurations "damper+" / "module+", run only when one of them is on: the default runs keep their state
# vector, hence the solver's error norm, bit for bit); offsets inside the block: ext.E_*
EXT_BLOCKS = (("thermal", thermal.STATES), ("aeration", aeration.STATES), ("free_play", freeplay.STATES))
# the mono tube's floating piston (floating.py) after the extension: configurations "damper_fp" / "module_fp",
# run for every mono tube (the extension's states rest unless their effects are on)
FP_BLOCKS = (("floating", floating.STATES),)
CONFIG_BLOCKS = {"valve": VALVE_BLOCKS, "damper": DAMPER_BLOCKS, "module": MODULE_BLOCKS,
                 "topmount": TOPMOUNT_BLOCKS, "active_valve": ACTIVE_BLOCKS,
                 "damper+": DAMPER_BLOCKS + EXT_BLOCKS, "module+": MODULE_BLOCKS + EXT_BLOCKS,
                 "damper_fp": DAMPER_BLOCKS + EXT_BLOCKS + FP_BLOCKS, "module_fp": MODULE_BLOCKS + EXT_BLOCKS + FP_BLOCKS}
SO, N_MODULE = _offsets(MODULE_BLOCKS)   # module offsets; the damper's are its first blocks
TO, N_TOPMOUNT = _offsets(TOPMOUNT_BLOCKS)
N_DAMPER = _offsets(DAMPER_BLOCKS)[1]
EO, _ = _offsets(EXT_BLOCKS)  # offsets inside the extension block
E_TW, E_GE, E_XS = EO["thermal"] + thermal.TW, EO["aeration"] + aeration.GE, EO["free_play"] + freeplay.XS
E_VS = EO["free_play"] + freeplay.VS
EXT_AT = {"damper+": N_DAMPER, "module+": N_MODULE, "damper_fp": N_DAMPER,
          "module_fp": N_MODULE}  # where the extension block starts
N_EXT = _offsets(EXT_BLOCKS)[1]
FP_AT = {"damper_fp": N_DAMPER + N_EXT, "module_fp": N_MODULE + N_EXT}  # where the floating piston's block starts


def states(configuration: str) -> tuple:
    return tuple(s for _, sts in CONFIG_BLOCKS[configuration] for s in sts)


def state_names(configuration: str) -> tuple[str, ...]:
    return tuple(f"{b}.{s[0]}" for b, sts in CONFIG_BLOCKS[configuration] for s in sts)


def scales(configuration: str) -> np.ndarray:
    return np.array([s[2] for s in states(configuration)], float)


OUTPUTS = ("displacement [m]", "velocity [m/s]", "stroke [m]", "rod force [N]", "top mount force [N]",
           "actuator force [N]", "rod acceleration [m/s^2]", "friction force [N]", "p rebound [Pa]",
           "p compression [Pa]", "p third tube [Pa]", "p reserve [Pa]", "p control [Pa]",
           "lift piston_rebound [m]", "lift piston_intake [m]", "lift base_compression [m]", "lift base_intake [m]",
           "lift main stage [m]", "lift pilot [m]", "flow piston [m^3/s]", "flow base [m^3/s]",
           "flow bypass [m^3/s]", "flow active valve [m^3/s]", "coil current [A]", "oil temperature [K]",
           "gas temperature [K]", "oil mass [kg]", "dissipated power [W]", "magnetic power [W]",
           "flow [m^3/s]", "dp [Pa]", "lift [m]", "top mount deflection [m]", "gas volume [m^3]",
           "floating piston position [m]")
(O_U, O_V, O_S, O_F_ROD, O_F_TM, O_F_ACT, O_A_ROD, O_F_MU, O_P_R, O_P_C, O_P_B, O_P_RES, O_P_K, O_X_PR, O_X_PI,
 O_X_BC, O_X_BI, O_X_M, O_X_P, O_Q_P, O_Q_BV, O_Q_BP, O_Q_A, O_I, O_T_OIL, O_T_GAS, O_MASS, O_DISS, O_MAG, O_Q_IN,
 O_DP, O_LIFT, O_X_TM, O_V_GAS, O_X_FP) = range(len(OUTPUTS))
N_OUT = len(OUTPUTS)
