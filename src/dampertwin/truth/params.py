"""The truth's parameters: the nominal part from the design's drawings
(geometry, oil, gas fill: nominal values only) and the truth's own
drawings and datasheets below, a sample's values (``truth.values`` in a
``dampertwin-lab 3`` sample), its effect switches, and the part as built
(areas, volumes and spring rates off their drawings by up to AS_BUILT,
drawn per sample).

Keys: ``<block>.<NAME>`` of layout.PARAM_NAMES, and the shim-stack
drawings ``<valve>.<a|b|r1|t1|n1|a2|t2|n2|gap|preload|w_s>`` from which
plate.py computes the stack's stiffness and areas.

The architecture (the design's ``architecture:``; passive.CODES) is the
truth parameter ``chambers.ARCH``. The parts an architecture lacks are not
built: their parameters are NaN (a twin tube: the solenoid valve and the
third tube's volume, bypass and wall; a mono tube also the base valves; the
twin tube keeps P_W, the reserve's rest pressure outside its pressure tube), so
a right-hand side that read one would fail loudly; the mono tube's gas has
no reserve oil beside it (the floating piston separates them).
"""

from __future__ import annotations

import math
import zlib

import numpy as np

from . import fluid, gas
from .passive import CODES, MONO, TRIPLE
from .layout import N_PARAMS, PARAM_NAMES, PO
from .plate import shape_ratio, stack

E_STEEL, NU_STEEL = 206e9, 0.3  # shim steel (SAE 1095 spring steel)
SHIMS = ("piston_rebound", "base_compression")
INTAKES = ("piston_intake", "base_intake")
SHIM_DRAWING = ("a", "b", "r1", "t1", "n1", "a2", "t2", "n2", "gap", "preload", "w_s")
AS_BUILT = 0.02  # largest relative deviation of an area, volume or spring rate from its drawing
# (block, name) of the areas, volumes and spring rates a real part has off its drawing
DEVIATING = (
    *((v, n) for v in SHIMS for n in ("K1", "K2", "A_EQ", "A_PORT", "A_BLEED", "DELTA")),
    *((v, n) for v in INTAKES for n in ("K_S", "F_S", "A_P", "A_HOLE")),
    ("active_valve", "K_P"), ("active_valve", "F_P0"), ("active_valve", "K_M"), ("active_valve", "A_F"),
    ("active_valve", "A_B"), ("active_valve", "F_S"), ("active_valve", "V_K"),
    ("chambers", "V_B"), ("chambers", "A_BP"), ("gas", "V_TOT"),
    ("mount", "K_E"), ("mount", "K_1"), ("mount", "K_2"), ("mount", "K_3"), ("seal", "F0"), ("fixture", "K_F"),
)
# effect switches of the truth: the first nine are on in a lab sample unless switched off there (the shipped
# samples' physics); the last four are hidden effects, OFF unless a sample names them (true: their nominal
# values below; a mapping: on, with the values it gives, keys of EFFECT_PARAMETERS)
EFFECTS = {"shim_friction": ("piston_rebound.FRICTION", "base_compression.FRICTION"),
           "gas_dissolution": ("gas.DISSOLVE",), "gas_heat_exchange": ("gas.HEAT",),
           "oil_thermal": ("chambers.THERMAL",), "payne": ("mount.PAYNE",), "fixture": ("fixture.ON",),
           "current_driver": ("active_valve.DRIVER",), "wall_compliance": (), "as_built": (),
           "band_eccentricity": (), "two_node_thermal": ("thermal.ON",), "top_mount_free_play": ("free_play.ON",),
           "air_entrainment": ("aeration.ON",)}
OFF_BY_DEFAULT = ("band_eccentricity", "two_node_thermal", "top_mount_free_play", "air_entrainment")
# an effect's parameters as a sample names them under ``effects:`` -> (truth key, lowest, highest) [SI]
EFFECT_PARAMETERS = {
    "band_eccentricity": {"eccentricity": ("chambers.BAND_ECC", 0.0, 0.95)},  # [-] offset / radial clearance
    "two_node_thermal": {"oil_capacity": ("thermal.C_OIL", 1.0, 1e6), "steel_capacity": ("thermal.C_W", 1.0, 1e6),
                         "oil_to_steel": ("thermal.G_OW", 1e-3, 1e9)},  # [J/K], [J/K], [W/K]
    "top_mount_free_play": {"clearance": ("free_play.GAP", 0.0, 5e-3), "stiffness": ("free_play.K", 1e5, 1e13),
                            "damping": ("free_play.LAM", 0.0, 10.0), "sleeve_mass": ("free_play.M_S", 1e-3, 10.0)},
    # [m] half-width of the play, [N/m^1.5], [s/m], [kg]
    "air_entrainment": {"onset_pressure": ("aeration.P_E", 1e3, 1e7), "fraction": ("aeration.PHI_E", 0.0, 1.0),
                        "release_time": ("aeration.TAU_E", 1e-3, 1e4)},  # [Pa], [-], [s]
}

# The truth's own drawings and datasheets (what the design file does not describe).
TRUTH_NOMINAL = {
    # oil: Murnaghan K' of mineral oils 10-12, thermal expansion 7e-4 1/K (Totten 2000, ch. 3)
    "oil.K1": 11.0, "oil.BETA_T": 7.0e-4, "oil.P_V": 2000.0, "viscosity_slope": 0.03,
    # thermal: 0.3 kg oil + 1.4 kg steel, 5 W/K to the air (Calvo et al., Int. J. Vehicle Design 2009)
    "chambers.C_TH": 1200.0, "chambers.HA": 5.0, "chambers.THERMAL": 1.0,
    # piston band: 8 um radial clearance over 8 mm (new part); bypass: six holes through 1.75 mm of wall
    "chambers.BAND_H": 8e-6, "chambers.BAND_L": 8e-3, "chambers.N_BP": 6.0, "chambers.L_BP": 1.75e-3,
    # reserve: nitrogen; thermal time constant 0.8 s; 150 cm^3 of reserve oil; Henry (air in mineral oil:
    # 9 % by volume per bar, Bunsen 0.09); surface dissolution over 120 s; entrained air: released over ~1 s,
    # dissolved over ~20 s (air release is far slower than vapour cavitation: Gholizadeh, Burton & Schoenau,
    # Int. J. Fluid Power 13 (2012) 7; with a 2 ms release the oil, saturated at the precharge, foamed within
    # a rebound stroke and the damper lost half its compression force)
    "gas.R_S": 296.8, "gas.C_V": 743.0, "tau_thermal": 0.8, "reserve_oil": 1.5e-4, "gas.S_H": 0.09,
    "gas.TAU_S": 120.0, "gas.ALPHA_N": 1e-5, "gas.TAU_REL": 1.0, "gas.TAU_DIS": 20.0, "gas.DISSOLVE": 1.0,
    "gas.HEAT": 1.0, "alpha_free": None,  # None: the design's oil.chi
    # shim stacks (drawings): radii [m], shim thickness [m] and count, crossover gap, preload [N], seat land
    "piston_rebound.a": 0.013, "piston_rebound.b": 0.008, "piston_rebound.r1": 0.009, "piston_rebound.t1": 3e-4,
    "piston_rebound.n1": 4, "piston_rebound.a2": 0.0115, "piston_rebound.t2": 3e-4, "piston_rebound.n2": 1,
    "piston_rebound.gap": 1.2e-4, "piston_rebound.preload": None, "piston_rebound.w_s": 5e-4,
    "base_compression.a": 0.012, "base_compression.b": 0.0075, "base_compression.r1": 0.0085,
    "base_compression.t1": 3e-4, "base_compression.n1": 4, "base_compression.a2": 0.0105,
    "base_compression.t2": 3e-4, "base_compression.n2": 1, "base_compression.gap": 1.2e-4,
    "base_compression.preload": None, "base_compression.w_s": 5e-4,
    # shim-to-shim friction (steel on steel in oil, mu ~ 0.1) with a 2 N/um interface stiffness; squeeze-film
    # damping ~0.6 of critical (THESIS-ERRATA 28 gives ~0.7 for the model's valves)
    **{f"{v}.{k}": x for v in SHIMS for k, x in (("MU", 0.1), ("K_MU", 2e6), ("C", 150.0), ("CD", 0.68),
                                                ("L_BLEED", 1e-3), ("K_C", 1e11), ("LAM_C", 0.5),
                                                ("EPS", 5e-7), ("FRICTION", 1.0))},
    # intake valves: coil spring rates and seat land width (drawings)
    "piston_intake.K_S": 6e5, "base_intake.K_S": 4.5e5, "piston_intake.w_s": 6e-4, "base_intake.w_s": 6e-4,
    **{f"{v}.{k}": x for v in INTAKES for k, x in (("C", 70.0), ("CD", 0.68), ("K_C", 1e11), ("LAM_C", 0.5),
                                                  ("EPS", 5e-7))},
    # solenoid valve: 4 ohm / 20 mH coil, PI driver at ~500 Hz on a 13.5 V supply; 3 mm pilot; 12 mm main stage;
    # pilot and main stage damped by their armature / damping orifices (less damping: the pilot oscillates
    # against the control chamber, a relief-valve instability, and costs 3x the steps; at 150 N s/m the main
    # stage still chattered at its crack pressure at 0.9 A, +-20 g on the rod in the 13 Hz test)
    "active_valve.R": 4.0, "active_valve.L": 0.02, "active_valve.KP": 60.0, "active_valve.KI": 1.2e4,
    "active_valve.U_MAX": 13.5, "active_valve.F_S": 3.74, "active_valve.I_S": 0.3, "active_valve.D_PL": 3e-3,
    "active_valve.W_PL": 3e-4, "active_valve.M_P": 2e-3, "active_valve.K_P": 8000.0, "active_valve.F_P0": 2.6,
    "active_valve.C_P": 60.0, "active_valve.XP_MAX": 3e-4, "active_valve.COS_JET": math.cos(math.radians(69.0)),
    "active_valve.A_F": 2.8e-7, "active_valve.L_F": 1e-3, "active_valve.V_K": 1e-6, "active_valve.D_M": 0.012,
    "active_valve.W_M": 5e-4, "active_valve.A_M": math.pi / 4 * 0.012 ** 2, "active_valve.A_K": 1.2e-4,
    "active_valve.M_M": 5e-3, "active_valve.K_M": 3.0e5, "active_valve.F_M0": 5.0, "active_valve.C_M": 800.0,
    "active_valve.XM_MAX": 1.5e-3, "active_valve.A_B": 6e-7, "active_valve.L_B": 1e-3, "active_valve.CD": 0.7,
    "active_valve.K_C": 1e10, "active_valve.LAM_C": 0.5, "active_valve.EPS": 2e-7, "active_valve.DRIVER": 1.0,
    # rod seal (lip seal, pressure-loaded: mu 0.1 x pi 22 mm x 1.5 mm contact)
    "seal.F0": 55.0, "seal.K_PR": 1e-5, "seal.C_V": 50.0, "seal.K_1": 4e6, "seal.K_2": 1e6, "seal.K_3": 2.5e5,
    "seal.W_1": 0.5, "seal.W_2": 0.3, "seal.W_3": 0.2, "seal.P_EPS": 1e4,
    # top mount rubber: backbone, three Maxwell branches (0.1 s, 2 ms, 0.1 ms), Kraus/Payne
    "mount.K_E": 1.2e6, "mount.K_E3": 8e10, "mount.K_1": 3e5, "mount.K_2": 2e5, "mount.K_3": 2e5,
    "mount.C_1": 3e4, "mount.C_2": 400.0, "mount.C_3": 20.0, "mount.PHI_INF": 0.5, "mount.A_C": 3e-4,
    "mount.M_K": 0.6, "mount.TAU_R": 0.2, "mount.TAU_M": 2.0, "mount.PAYNE": 1.0,
    # fixture: 12 kg crosshead on the load cell, 650 Hz, 4 % damping
    "fixture.M_F": 12.0, "fixture.K_F": 12.0 * (2 * math.pi * 650.0) ** 2,
    "fixture.C_F": 2 * 0.04 * math.sqrt(12.0 * 12.0 * (2 * math.pi * 650.0) ** 2), "fixture.ON": 1.0,
    # mono tube's floating piston (floating.py): an aluminium disc 46 mm x 18 mm with its O-ring, 2700 kg/m^3 x
    # pi/4 0.046^2 x 0.018 m = 0.081 kg (engineering estimate: Dixon, The Shock Absorber Handbook, 2nd ed. 2007,
    # sec. 1.4 draws such a piston); O-ring (2.62 mm cord, ~15 % squeeze) friction F_C L_p ~ 0.14 N/mm x pi 46 mm
    # = 20 N (Parker O-Ring Handbook ORD 5700, 2007, sec. 5.6, fig. 5-13; engineering estimate), sticking over
    # ~20 um (K = F0 / 20 um = 1e6 N/m), oil film 20 N s/m (engineering estimate, as the rod seal's C_V / 2.5)
    "floating.M": 0.081, "floating.F0": 20.0, "floating.K": 1.0e6, "floating.C_V": 20.0,
    # hidden effects (off unless a sample names them; these values when it says `true`):
    # a worn band's piston off the bore's axis by half its clearance
    "chambers.BAND_ECC": 0.5,
    # two thermal nodes: 0.3 kg oil x 1.9 kJ/(kg K), 1.4 kg steel x 0.45 kJ/(kg K) (carbon steel, Incropera
    # table A.1), 250 W/(m^2 K) over 0.04 m^2; C_OIL + C_W = chambers.C_TH, the one-node law's capacity
    "thermal.C_OIL": 570.0, "thermal.C_W": 630.0, "thermal.G_OW": 10.0, "thermal.ON": 0.0,
    # top-mount play +-0.1 mm; steel washer on the sleeve: Hertz-like 2e10 N/m^1.5, restitution ~0.85 at 1 m/s
    # (LAM = 3 (1 - e) / (2 v), Gilardi & Sharf 2002); 0.25 kg inner sleeve and bearing
    "free_play.GAP": 1e-4, "free_play.K": 2e10, "free_play.LAM": 0.2, "free_play.EPS": 1e-8, "free_play.M_S": 0.25,
    "free_play.ON": 0.0,
    # entrainment below 2.5 bar abs, up to 5 % gas by volume at vacuum, released over 1 s
    "aeration.P_E": 2.5e5, "aeration.PHI_E": 0.05, "aeration.TAU_E": 1.0, "aeration.ON": 0.0,
}
VALUE_KEYS = frozenset(PARAM_NAMES) | frozenset(TRUTH_NOMINAL)
# the parameters of the parts an architecture lacks (not built: NaN), by block or "block.NAME"
ABSENT = {"twin_tube": ("active_valve", "chambers.V_B", "chambers.A_BP", "chambers.KAPPA_TT"),
          "mono_tube": ("active_valve", "chambers.V_B", "chambers.A_BP", "chambers.KAPPA_TT", "chambers.P_W",
                        "base_compression", "base_intake")}


class TruthParameterError(ValueError):
    """An unknown truth key or effect (the message names it)."""


def nominal(design) -> dict:
    """The truth's inputs for a nominal design: its drawings and oil, the
    truth's own drawings (TRUTH_NOMINAL)."""
    d = design
    v = dict(TRUTH_NOMINAL)
    v["architecture"] = getattr(d, "architecture", "triple_tube_semi_active")
    v["alpha_free"] = float(d["oil.chi"])
    for s, pre in zip(SHIMS, ("piston_rebound.F_preload", "base_compression.F_preload")):
        v[f"{s}.preload"] = float(d[pre])
    v.update({
        "oil.RHO0": float(d["oil.rho_oil"]), "oil.K0": float(d["oil.K_oil"]),
        "oil.P_REF": float(d["constants.P_ref"]),
        "oil.T0": float(d["oil.T"]), "oil.P_ATM": float(d["constants.P_atm"]), "nu": float(d["oil.nu"]),
        "P0": float(d["oil.P_0"]), "T": float(d["oil.T"]), "V_gas0": float(d["constants.V_gas0"]),
        "chambers.D_PT": float(d["geometry.D_PT"]), "D_R": float(d["geometry.D_R"]),
        "chambers.L_R0": float(d["geometry.l_r0"]), "chambers.L_C0": float(d["geometry.l_c0"]),
        "chambers.V_B": float(d["geometry.V_b"]), "chambers.M_ROD": float(d["geometry.M_rod"]),
        "chambers.A_BP": float(d["constants.A_bypass"]), "E": float(d["third_tube.E"]),
        "nu_p": float(d["third_tube.nu_p"]), "pt_r_i": float(d["constants.pt_r_i"]),
        "pt_r_o": float(d["constants.pt_r_o"]), "tt_r_i": float(d["third_tube.r_i"]),
        "tt_r_o": float(d["third_tube.r_o"]), "tt_ratio": float(d["constants.wall_ratio_third_tube"]),
    })
    for s in SHIMS:
        g = d.group(s)
        v[f"{s}.M"] = float(g["m_v"])
        v[f"{s}.A_PORT"] = float(g["A_slot"])
        v[f"{s}.A_BLEED"] = float(g["A_bleed"])
        v[f"{s}.X_MAX"] = float(d[f"constants.x_max_{s}"])
    for s in INTAKES:
        g = d.group(s)
        v[f"{s}.M"] = float(g["m_v"])
        v[f"{s}.A_HOLE"] = float(g["A_slot"])
        v[f"{s}.F_S"] = float(g["F_preload"])
        v[f"{s}.r_in"] = 0.5 * float(g["D_i"])  # the seat ring at the drawing's inner disc diameter
        v[f"{s}.X_MAX"] = float(d[f"constants.x_max_{s}"])
    return v


def check_values(values: dict, where: str) -> None:
    """Every key names a truth parameter or drawing (TruthParameterError naming it)."""
    bad = [k for k in values if k not in VALUE_KEYS]
    if bad:
        raise TruthParameterError("; ".join(f"{where}.{k}: unknown truth key" for k in bad))


def check_effects(effects: dict, where: str) -> None:
    """Every effect is known and set to true / false or, for a hidden
    effect with parameters, to a mapping of them (finite, in range); a
    TruthParameterError names every bad key."""
    bad = []
    for k, val in effects.items():
        if k not in EFFECTS:
            bad.append(f"{where}.{k}: unknown effect; expected one of {', '.join(sorted(EFFECTS))}")
        elif isinstance(val, dict):
            known = EFFECT_PARAMETERS.get(k, {})
            if not known:
                bad.append(f"{where}.{k}: {val!r}; expected true or false (the effect has no parameters)")
            for q, x in val.items():
                if q not in known:
                    if known:
                        bad.append(f"{where}.{k}.{q}: unknown parameter; expected {', '.join(sorted(known))}")
                elif not (isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                          and known[q][1] <= x <= known[q][2]):
                    bad.append(f"{where}.{k}.{q}: {x!r}; expected a number in [{known[q][1]:g}, {known[q][2]:g}] (SI)")
        elif not isinstance(val, bool):
            bad.append(f"{where}.{k}: {val!r}; expected true, false"
                       + (f" or a mapping of {', '.join(sorted(EFFECT_PARAMETERS[k]))}" if k in EFFECT_PARAMETERS
                          else ""))
    if bad:
        raise TruthParameterError("; ".join(bad))


def effect_settings(effects: dict | None) -> tuple[dict, dict]:
    """(switch per effect, truth values the effects' mappings give) of a
    sample's ``effects:``; the hidden effects (OFF_BY_DEFAULT) are off
    unless named, the others on."""
    on = {k: k not in OFF_BY_DEFAULT for k in EFFECTS}
    values = {}
    for k, val in dict(effects or {}).items():
        on[k] = True if isinstance(val, dict) else val
        if isinstance(val, dict):
            values.update({EFFECT_PARAMETERS[k][q][0]: float(x) for q, x in val.items()})
    return on, values


def derive(v: dict, effects: dict | None = None, as_built_seed: int | None = None,
           as_built: float = AS_BUILT) -> np.ndarray:
    """The packed parameter vector (layout.PARAM_NAMES; run block left 0)
    of the part described by ``v`` (:func:`nominal` updated by a sample's
    values), with effect switches ``effects`` (default all on) and, when
    ``as_built_seed`` is given, the part as built. An effect's mapping
    (check_effects) switches it on with its values, over ``v``'s."""
    check_effects(dict(effects or {}), "effects")
    effects, eff_values = effect_settings(effects)
    v = {**v, **eff_values}
    q = {k: x for k, x in v.items() if k in PARAM_NAMES}
    arch = v.get("architecture", "triple_tube_semi_active")
    if arch not in CODES:
        raise TruthParameterError(f"architecture: {arch!r}; expected one of {', '.join(CODES)}")
    q["chambers.ARCH"] = float(CODES[arch])
    if not effects["band_eccentricity"]:
        q["chambers.BAND_ECC"] = 0.0
    q["oil.WALTHER_A"], q["oil.WALTHER_B"] = fluid.walther_coefficients(v["nu"], v["T"], v["viscosity_slope"])
    D_PT, D_R = q["chambers.D_PT"], v["D_R"]
    q["chambers.A_B"] = math.pi / 4 * D_PT ** 2
    q["chambers.A_R"] = q["chambers.A_B"] - math.pi / 4 * D_R ** 2
    wall = effects["wall_compliance"]
    q["chambers.KAPPA_PT"] = fluid.lame_compliance(v["pt_r_i"], v["pt_r_o"], v["E"], v["nu_p"]) if wall else 0.0
    q["chambers.KAPPA_TT"] = (fluid.lame_compliance(v["tt_r_i"], v["tt_r_o"], v["E"], v["nu_p"]) * v["tt_ratio"]
                              if wall else 0.0)
    q["chambers.P_W"] = v["P0"]  # the reservoir's rest pressure, which loads the third tube's wall from outside
    q["chambers.T_AMB"] = v["T"]
    if CODES[arch] == MONO:  # the gas behind the floating piston: no reserve oil
        q["gas.V_TOT"] = v["V_gas0"]
    else:
        q["gas.V_TOT"] = v["V_gas0"] + v["reserve_oil"]
    q["gas.H"] = v["P0"] * v["V_gas0"] / (v["gas.R_S"] * v["T"]) * v["gas.C_V"] / v["tau_thermal"]
    q["gas.K_H"] = v["gas.S_H"] * _gas_density_ref(v) / v["oil.P_REF"]  # [kg/(m^3 Pa)]
    gas_inputs = {k[4:]: v[k] for k in v if k.startswith("gas.")}
    # the oil's gas content: saturated at the gas fill it touches (triple, twin tube); a mono tube's oil never
    # meets its gas (the floating piston between): it holds the air of its filling at atmospheric pressure
    # (Henry's law), so at the precharge its free gas dissolves down to the nuclei (Dixon 2007, sec. 1.4: the
    # mono tube's separated gas against aeration)
    P_sat = v["oil.P_ATM"] if CODES[arch] == MONO else v["P0"]
    q["gas.ALPHA_TOT"] = gas.equilibrium_free_gas(v["alpha_free"], P_sat, gas_inputs, v["oil.P_REF"])
    for s in SHIMS:
        face = stack(v[f"{s}.a"], v[f"{s}.b"], v[f"{s}.t1"], int(v[f"{s}.n1"]), E_STEEL, NU_STEEL, v[f"{s}.r1"])
        back = stack(v[f"{s}.a2"], v[f"{s}.b"], v[f"{s}.t2"], int(v[f"{s}.n2"]), E_STEEL, NU_STEEL, v[f"{s}.r1"])
        q[f"{s}.K1"], q[f"{s}.A_EQ"] = face["k"], face["area"]
        q[f"{s}.K2"] = back["k"]
        q[f"{s}.PSI"] = shape_ratio(v[f"{s}.a"], v[f"{s}.b"], v[f"{s}.a2"], v[f"{s}.t1"], E_STEEL, NU_STEEL)
        q[f"{s}.GAP"] = v[f"{s}.gap"]
        q[f"{s}.DELTA"] = v[f"{s}.preload"] / face["k"]
        q[f"{s}.R_S"], q[f"{s}.W_S"] = v[f"{s}.a"], v[f"{s}.w_s"]
    for s in INTAKES:
        r_in = v[f"{s}.r_in"]
        q[f"{s}.R_IN"], q[f"{s}.R_OUT"] = r_in, r_in + v[f"{s}.w_s"]
        q[f"{s}.A_P"] = fluid.land_area(r_in, r_in + v[f"{s}.w_s"])
    for eff, keys in EFFECTS.items():
        for k in keys:
            q[k] = 1.0 if effects[eff] else 0.0
    p = np.zeros(N_PARAMS)
    missing = [k for k in PARAM_NAMES if k not in q and not k.startswith("run.")]
    if missing:
        raise TruthParameterError(f"truth parameters not set: {', '.join(missing)}")
    if as_built_seed is not None and effects["as_built"]:
        rng = np.random.default_rng(as_built_seed)
        for b, n in DEVIATING:
            q[f"{b}.{n}"] *= 1.0 + as_built * rng.uniform(-1.0, 1.0)
    if CODES[arch] != TRIPLE:  # the parts the architecture lacks are not built
        for k in q:
            if k in ABSENT[arch] or k.split(".")[0] in ABSENT[arch]:
                q[k] = math.nan
    for i, k in enumerate(PARAM_NAMES):
        if not k.startswith("run."):
            p[i] = q[k]
    return p


def _gas_density_ref(v: dict) -> float:
    """Nitrogen density [kg/m^3] at P_ref and the oil's temperature."""
    return v["oil.P_REF"] / (v["gas.R_S"] * v["T"])


def as_built_seed(seed_offset: int) -> int:
    """The as-built draw of a sample (its seed_offset)."""
    return int(seed_offset + zlib.crc32(b"truth/as-built")) % 2**32


def index(name: str) -> int:
    """Position of ``block.NAME`` in the parameter vector."""
    b, n = name.split(".")
    from .layout import PARAM_BLOCKS
    return PO[b] + dict(PARAM_BLOCKS)[b].index(n)


__all__ = ["nominal", "derive", "index"]
