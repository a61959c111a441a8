"""The assembled model's vectors, derived from the submodels' declarations.

Nothing here is written by hand per state or parameter: ``P`` numbers the
parameters that every submodel declares (plus one block per valve), ``S``,
``B`` and ``T`` number the states of the damper / module, flow-bench and
top-mount configurations in the order the submodels are listed below, and
``O`` the output channels. They are IntEnums, so the compiled functions see
plain integer constants.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from . import (active_valve, active_valve_driver, active_valve_lag, aeration, bench, chambers, fixture_resonance, fluid,
               gas_release, inputs, oil_thermal, piston_leakage, rod, rod_friction, rod_friction_asymmetric,
               seal_friction_pressure, top_mount, top_mount_backlash, valve_friction_current, valves)

from .declarations import Parameter, State, index_enum
from .valves import SHIM_VALVES, V_SIZE, VALVE_NAMES, valve_states

# ---- parameters: every submodel's declarations, then four valve blocks
SUBMODELS = (chambers, fluid, valves, piston_leakage, rod_friction, top_mount, rod, active_valve, bench, inputs,
             active_valve_lag, aeration, valve_friction_current, oil_thermal, rod_friction_asymmetric,
             top_mount_backlash, seal_friction_pressure, fixture_resonance, active_valve_driver, gas_release)
PARAMETERS: tuple[Parameter, ...] = tuple(p for m in SUBMODELS for p in m.PARAMETERS)
P = index_enum("P", [p.name for p in PARAMETERS] + ["VALVES"], __name__)
N_PARAMS = len(PARAMETERS) + 4 * V_SIZE
PARAM_NAMES = tuple(p.name for p in PARAMETERS) + tuple(
    f"{v}.{q.name}" for v in VALVE_NAMES for q in valves.VALVE_PARAMETERS)

# ---- configurations and their states
CFG_VALVE, CFG_DAMPER, CFG_MODULE, CFG_TOPMOUNT = 0, 1, 2, 4
CONFIGURATIONS = {"valve": CFG_VALVE, "damper": CFG_DAMPER, "module": CFG_MODULE, "topmount": CFG_TOPMOUNT}
# Extended damper / module: the same states plus the states of the effects
# that need one (appended at the end), used only when one of those effects is
# on (``variant``), so a run with them off has exactly the states, error norm
# and results of the model without them.
CFG_DAMPER_X, CFG_MODULE_X = 5, 6
EXTENDED = {CFG_DAMPER: CFG_DAMPER_X, CFG_MODULE: CFG_MODULE_X}
BASE_CONFIGURATION = {CFG_DAMPER_X: CFG_DAMPER, CFG_MODULE_X: CFG_MODULE}
STATE_EFFECTS = ("E_AV_LAG", "E_VALVE_FRICTION", "E_THERMAL", "E_AERATION",  # switches of the effects with states
                 "E_FIXTURE", "E_AV_DRIVER", "E_GAS_RELEASE")

# A configuration is a sequence of state blocks, one per submodel instance;
# each submodel reads and writes its own states at its block's offset.
_DAMPER_BLOCKS = (
    ("chambers", chambers.STATES),
    *((v, valve_states(v, k)) for k, v in enumerate(VALVE_NAMES)),
    ("rod_friction", rod_friction.STATES),
)
_MODULE_BLOCKS = _DAMPER_BLOCKS + (("rod", rod.STATES), ("top_mount", top_mount.STATES))
_BENCH_BLOCKS = (("bench", bench.STATES), ("valve", bench.VALVE_STATES))
_TOPMOUNT_BLOCKS = (("top_mount", top_mount.STATES),)
_EFFECT_STATES = (active_valve_lag.STATES + valve_friction_current.STATES + oil_thermal.STATES + aeration.STATES
                  + fixture_resonance.STATES + active_valve_driver.STATES + gas_release.STATES)
_EFFECT_BLOCKS = (("effects", _EFFECT_STATES),)


def _states(blocks) -> tuple[State, ...]:
    return tuple(s for _, states in blocks for s in states)


def _offsets(name, blocks):
    """IntEnum of the first state index of each block."""
    starts, i = {}, 0
    for block, states in blocks:
        starts[block] = i
        i += len(states)
    return IntEnum(name, starts, module=__name__)


STATES: dict[int, tuple[State, ...]] = {
    CFG_VALVE: _states(_BENCH_BLOCKS), CFG_DAMPER: _states(_DAMPER_BLOCKS), CFG_MODULE: _states(_MODULE_BLOCKS),
    CFG_TOPMOUNT: _states(_TOPMOUNT_BLOCKS),
    CFG_DAMPER_X: _states(_DAMPER_BLOCKS + _EFFECT_BLOCKS), CFG_MODULE_X: _states(_MODULE_BLOCKS + _EFFECT_BLOCKS),
}
SB = _offsets("SB", _MODULE_BLOCKS)  # damper / module (the damper is the module's first blocks)
BB = _offsets("BB", _BENCH_BLOCKS)
TB = _offsets("TB", _TOPMOUNT_BLOCKS)
S = index_enum("S", [s.name for s in STATES[CFG_MODULE]], __name__)  # every state by name
B = index_enum("B", [s.name for s in STATES[CFG_VALVE]], __name__)
T = index_enum("T", [s.name for s in STATES[CFG_TOPMOUNT]], __name__)
N_DAMPER = len(STATES[CFG_DAMPER])
N_MODULE = len(STATES[CFG_MODULE])
N_STATES = {cfg: len(st) for cfg, st in STATES.items()}
EX = index_enum("EX", [s.name for s in _EFFECT_STATES], __name__)  # offsets inside the effect-state block
EB_DAMPER, EB_MODULE = N_DAMPER, N_MODULE  # where the effect-state block starts in CFG_DAMPER_X / CFG_MODULE_X
assert all(f"F_dahl_{v}" in S.__members__ for v in SHIM_VALVES)

# ---- output channels computed at every output time
OUTPUTS = (
    ("displacement [m]", "U"), ("velocity [m/s]", "V"), ("stroke [m]", "S"),
    ("rod force [N]", "F_D"), ("top mount force [N]", "F_TM"), ("rod acceleration [m/s^2]", "A_ROD"),
    ("friction force [N]", "F_MU"),
    ("p rebound [Pa]", "P_R"), ("p compression [Pa]", "P_C"), ("p third tube [Pa]", "P_B"),
    ("p reserve [Pa]", "P_RES"),
    *((f"lift {v} [m]", f"X{k}") for k, v in enumerate(VALVE_NAMES)),
    *((f"flow {v} [m^3/s]", f"Q{k}") for k, v in enumerate(VALVE_NAMES)),
    ("flow bypass [m^3/s]", "Q_BP"), ("flow active valve [m^3/s]", "Q_A"),
    ("storage rebound [m^3/s]", "ST_R"), ("storage compression [m^3/s]", "ST_C"),
    ("storage third tube [m^3/s]", "ST_B"), ("gas volume rate [m^3/s]", "DVG"),
    ("oil temperature [K]", "T_OIL"),
)
O = index_enum("O", [n for _, n in OUTPUTS], __name__)
N_OUT = len(OUTPUTS)


class ParamView:
    """Read a packed parameter vector by name: ``q["K_OIL"]``, or a valve
    block ``q.block("VALVES", k, V_SIZE)`` (for initial-state functions)."""

    def __init__(self, p: np.ndarray):
        self.p = p

    def __getitem__(self, name: str) -> float:
        return float(self.p[P[name]])

    def block(self, base: str, k: int, size: int) -> np.ndarray:
        o = int(P[base]) + k * size
        return self.p[o:o + size]


def variant(cfg: int, p: np.ndarray) -> int:
    """The configuration to integrate for parameters p: the extended one when
    an effect with states is switched on, else ``cfg`` itself."""
    if cfg in EXTENDED and any(p[P[e]] > 0.5 for e in STATE_EFFECTS):
        return EXTENDED[cfg]
    return cfg


def base_configuration(cfg: int) -> int:
    """CFG_DAMPER for CFG_DAMPER_X etc.; other configurations unchanged."""
    return BASE_CONFIGURATION.get(cfg, cfg)


def state_scales(cfg: int) -> np.ndarray:
    """Declared typical magnitudes of the configuration's states [SI]."""
    return np.array([s.scale for s in STATES[cfg]], float)


def initial_state(p: np.ndarray, cfg: int) -> np.ndarray:
    """Declared rest state of the configuration for parameters ``p``."""
    q = ParamView(p)
    return np.array([s.initial(q) if callable(s.initial) else float(s.initial) for s in STATES[cfg]], float)


def state_names(cfg: int) -> tuple[str, ...]:
    return tuple(s.name for s in STATES[cfg])
