"""What a design description must contain: the 105 parameters of thesis
table 5.1, the unnumbered equation constants, and the effect switches.

The registry fixes, for each number, the group, the python name and the SI
unit the model expects. A design file may choose values, types, sources and
bounds, but not what a number means. Units are written as plain strings
("N/m", "N*s/m", "m^2"); "-" is dimensionless.
"""

from __future__ import annotations

from typing import NamedTuple

TYPES = ("D", "F", "C", "T")
TYPE_MEANING = {
    "D": "design, from drawings",
    "F": "fixed, from literature",
    "C": "calibrated",
    "T": "test condition",
}

# Every unit the project accepts. Anything else (mm, bar, l/min, degC, ...)
# is rejected: values are stored in SI.
SI_UNITS = frozenset(
    {
        "-", "m", "m^2", "m^3", "kg", "s", "K", "A", "N", "Pa", "rad",
        "1/s", "1/m", "m/s", "m^2/s", "m^3/s", "kg/m^3", "N/m", "N*s/m",
        "1/K", "J/K", "W/K", "N/A", "m^2/N", "N/Pa", "Hz", "A/s",
    }
)


class Spec(NamedTuple):
    no: int
    group: str
    name: str
    unit: str
    kind: str = "scalar"  # "scalar" | "vector" | "table"


def _shim(start: int, group: str) -> list[Spec]:
    """Shim-stack valve parameters, table 5.1 nos. 34-51 / 69-86."""
    names = [
        ("D_d", "m"), ("D_i", "m"), ("Cq_max", "-"), ("lambda_crit", "-"),
        ("A_bleed", "m^2"), ("Cq_bleed", "-"), ("A_slot", "m^2"), ("Cq_slot", "-"),
        ("m_v", "kg"), ("c_v", "N*s/m"), ("sigma0", "N/m"), ("F_c", "N"),
        ("alpha", "-"), ("F_preload", "N"), ("a", "N"), ("b", "1/m"), ("c", "N"),
        ("d", "1/m"),
    ]
    return [Spec(start + k, group, n, u) for k, (n, u) in enumerate(names)]


def _intake(start: int, group: str) -> list[Spec]:
    """Intake (check) valve parameters, table 5.1 nos. 53-68 / 87-102."""
    names = [
        ("D_d", "m"), ("D_i", "m"), ("D_c", "m"), ("D_h", "m"), ("Cq_max", "-"),
        ("lambda_crit", "-"), ("A_slot", "m^2"), ("Cq_slot", "-"), ("m_v", "kg"),
        ("c_v", "N*s/m"), ("F_preload", "N"), ("a", "N"), ("b", "1/m"), ("c", "N"),
        ("d", "1/m"), ("x_v0", "m"),
    ]
    return [Spec(start + k, group, n, u) for k, (n, u) in enumerate(names)]


PARAMETERS: tuple[Spec, ...] = tuple(
    [
        Spec(1, "geometry", "M_rod", "kg"),
        Spec(2, "geometry", "D_PT", "m"),
        Spec(3, "geometry", "D_R", "m"),
        Spec(4, "geometry", "V_b", "m^3"),
        Spec(5, "geometry", "l_c0", "m"),
        Spec(6, "geometry", "l_r0", "m"),
        Spec(7, "oil", "K_oil", "Pa"),
        Spec(8, "oil", "rho_oil", "kg/m^3"),
        Spec(9, "oil", "nu", "m^2/s"),
        Spec(10, "oil", "P_sat", "Pa"),
        Spec(11, "oil", "P_vap", "Pa"),
        Spec(12, "oil", "chi", "-"),
        Spec(13, "oil", "Gamma", "-"),
        Spec(14, "oil", "P_0", "Pa"),
        Spec(15, "oil", "T", "K"),
        Spec(16, "third_tube", "E", "Pa"),
        Spec(17, "third_tube", "nu_p", "-"),
        Spec(18, "third_tube", "r_o", "m"),
        Spec(19, "third_tube", "r_i", "m"),
        Spec(20, "top_mount", "R", "1/s"),
        Spec(21, "top_mount", "p0", "-"),
        Spec(22, "top_mount", "p1", "-"),
        Spec(23, "top_mount", "p2", "-"),
        Spec(24, "top_mount", "q0", "-"),
        Spec(25, "top_mount", "q1", "-"),
        Spec(26, "top_mount", "q2", "-"),
        Spec(27, "top_mount", "k0", "N/m"),
        Spec(28, "top_mount", "k1", "N/m"),
        Spec(29, "top_mount", "k2", "N/m"),
        Spec(30, "top_mount", "c0", "N*s/m"),
        Spec(31, "top_mount", "c1", "N*s/m"),
        Spec(32, "top_mount", "c2", "N*s/m"),
        Spec(33, "top_mount", "F_LD", "N", "vector"),
    ]
    + _shim(34, "piston_rebound")
    + [Spec(52, "active_valve", "pq_map", "m^3/s", "table")]
    + _intake(53, "piston_intake")
    + _shim(69, "base_compression")
    + _intake(87, "base_intake")
    + [
        Spec(103, "rod_friction", "F_c", "N"),
        Spec(104, "rod_friction", "F_s", "N"),
        Spec(105, "rod_friction", "k_b", "N/m"),
    ]
)
BY_NUMBER = {s.no: s for s in PARAMETERS}
GROUPS = tuple(dict.fromkeys(s.group for s in PARAMETERS))
VALVES = ("piston_rebound", "piston_intake", "base_compression", "base_intake")
SHIM_VALVES = ("piston_rebound", "base_compression")
INTAKE_VALVES = ("piston_intake", "base_intake")

# Equation constants table 5.1 leaves out (DESIGN.md §3): name -> SI unit.
CONSTANTS: dict[str, str] = {
    "P_atm": "Pa",
    "P_ref": "Pa",
    "T_ref": "K",
    "rho_gas": "kg/m^3",
    "V_gas0": "m^3",
    "pt_r_i": "m",
    "pt_r_o": "m",
    "wall_ratio_third_tube": "-",
    "A_bypass": "m^2",
    "Cq_bypass": "-",
    "p_transition": "Pa",
    "zeta": "rad",
    "k_contact": "N/m",
    "zeta_contact": "-",
    "delta_contact": "m",
    "x_max_piston_rebound": "m",
    "x_max_piston_intake": "m",
    "x_max_base_compression": "m",
    "x_max_base_intake": "m",
    "s2": "N*s/m",
    "c_comp": "N*s/m",
    "vd": "m/s",
    "a_s": "m/s",
    "alpha_s": "-",
    "y_unit": "m",
    "w_unit": "m/s",
}
CONSTANT_TYPES = ("D", "F")

# Optional physical effects (every one can be switched off).
EFFECTS: dict[str, str] = {
    "gas_content": "free gas in the emulsion, eq. 4.14-4.16 (off: K = K_oil)",
    "wall_compliance": "tube wall compliance, eq. 4.17-4.18",
    "cavitation": "chamber pressure floor at the vapour pressure",
    "valve_stiction": "squeeze-film stiction on intake valves, eq. 4.25",
    "shim_friction": "Dahl friction on shim valves, eq. 4.26",
    "jet_force": "flow momentum force on valves, eq. 4.24",
    "flow_number_cq": "Cq(lambda) of eq. 4.30-4.31 (off: Cq = Cq_max)",
    "slot_restriction": "valve slot orifice in series with the opening",
    "rod_friction": "LuGre rod friction, eq. 4.38-4.41",
    "top_mount_dynamics": "AutoBushFD dynamic branches, eq. 4.32-4.36 (off: static curve only)",
    "piston_leakage": "laminar leakage past the piston band (left out by the thesis, 4.4)",
    "active_valve_lag": "first-order lag of the active valve's opening behind its static P/Q map (thesis 7.3)",
    "aeration": "free air in the compression chamber, released / dissolved at finite rates (thesis 7.3)",
    "valve_friction_current": "current-dependent Coulomb friction of the active valve's spool, with memory (thesis 7.3)",
    "oil_thermal": "oil temperature rising with dissipated power; viscosity, the oil's bulk modulus, oil "
                   "expansion and gas pressure follow it",
    "rod_friction_asymmetric": "direction-dependent film friction of the rod seal (rebound vs compression)",
    "top_mount_backlash": "free play of the top mount (smoothed dead zone)",
    "seal_friction_pressure": "rod seal friction growing with the rebound-chamber pressure",
    "fixture_resonance": "the rig's fixture resonating on the load cell (measurement chain: the force channel)",
    "active_valve_driver": "coil and current-driver dynamics of the active valve (shows only with current steps)",
    "gas_release": "the undissolved gas share of eq. 4.14 as a state per chamber, released / dissolved at finite "
                   "rates",
}

# Effects that modify another effect's equations and do nothing without it
# (effect -> the effect it needs on): rod_friction.friction scales or raises
# the LuGre levels of eq. 4.41; gas_release delays eq. 4.14's gas share.
EFFECT_NEEDS: dict[str, str] = {
    "rod_friction_asymmetric": "rod_friction",
    "seal_friction_pressure": "rod_friction",
    "gas_release": "gas_content",
}

# Parameters of the optional effects (design key ``effect_parameters:``),
# "<effect>.<name>" -> (SI unit, physical range). Not numbered: the 105
# parameters of table 5.1 stay 105.
EFFECT_PARAMETERS: dict[str, tuple[str, "Range"]] = {}  # filled below Range

# Columns of the active-valve P/Q map (parameter no. 52).
MAP_COLUMNS = ("current [A]", "dp [Pa]", "flow [m^3/s]")


# ---------------------------------------------------------------- physical ranges
class Range(NamedTuple):
    """An interval of physically meaningful values (SI); None = unbounded."""

    lo: float | None = None
    hi: float | None = None
    lo_incl: bool = False
    hi_incl: bool = False

    def contains(self, v: float) -> bool:
        if self.lo is not None and not (v >= self.lo if self.lo_incl else v > self.lo):
            return False
        if self.hi is not None and not (v <= self.hi if self.hi_incl else v < self.hi):
            return False
        return True

    def describe(self) -> str:
        parts = []
        if self.lo is not None:
            parts.append(f"{'>=' if self.lo_incl else '>'} {self.lo:g}")
        if self.hi is not None:
            parts.append(f"{'<=' if self.hi_incl else '<'} {self.hi:g}")
        return " and ".join(parts) or "any value"


POS = Range(0.0)                                   # > 0
NONNEG = Range(0.0, lo_incl=True)                  # >= 0
NONPOS = Range(hi=0.0, hi_incl=True)               # <= 0
COEF = Range(0.0, 1.0, hi_incl=True)               # discharge coefficient, 0 < Cq <= 1
TEMPERATURE = Range(200.0, 500.0, True, True)      # K (a value in degC is caught)


def upto(hi: float, zero: bool = False) -> Range:
    """A positive (``zero``: non-negative) value at most ``hi`` [SI]: the upper physical limit of a damper part."""
    return Range(0.0, hi, zero, True)


# Upper limits of a road-vehicle damper's parts (SI), far above any real one yet far below a unit mix-up
# (mm written as m, bar as Pa) or a runaway value: bores and discs <= 0.3 m, stroke lengths <= 2 m, valve
# lifts <= 50 mm, flow areas <= 0.01 m^2 (100 cm^2), volumes <= 50 l, the rod <= 50 kg, a valve <= 1 kg,
# pressures <= 1e8 Pa (1000 bar).
DIAMETER, LENGTH, LIFT, AREA, VOLUME = upto(0.3), upto(2.0), upto(0.05), upto(0.01), upto(0.05)
ROD_MASS, VALVE_MASS, PRESSURE = upto(50.0), upto(1.0), upto(1e8)

_SHIM_RANGES = {
    "D_d": DIAMETER, "D_i": DIAMETER, "Cq_max": COEF, "lambda_crit": POS, "A_bleed": upto(0.01, zero=True),
    "Cq_bleed": COEF, "A_slot": AREA, "Cq_slot": COEF, "m_v": VALVE_MASS, "c_v": NONNEG, "sigma0": NONNEG, "F_c": POS, "alpha": POS,
    "F_preload": NONNEG, "a": NONNEG, "b": NONNEG, "c": NONPOS, "d": NONPOS,
}
_INTAKE_RANGES = {
    "D_d": DIAMETER, "D_i": DIAMETER, "D_c": DIAMETER, "D_h": DIAMETER, "Cq_max": COEF, "lambda_crit": POS,
    "A_slot": AREA, "Cq_slot": COEF, "m_v": VALVE_MASS, "c_v": NONNEG, "F_preload": NONNEG, "a": NONNEG,
    "b": NONNEG, "c": NONPOS, "d": NONPOS, "x_v0": LIFT,
}

# Every scalar parameter ("group.name") and constant ("constants.NAME") with
# its physical range. Stated once: the loader checks values and C bounds here.
RANGES: dict[str, Range] = {
    "geometry.M_rod": ROD_MASS, "geometry.D_PT": DIAMETER, "geometry.D_R": DIAMETER, "geometry.V_b": VOLUME,
    "geometry.l_c0": LENGTH, "geometry.l_r0": LENGTH,
    "oil.K_oil": Range(1e7, 1e11, True, True),      # Pa: mineral oils ~1.5e9; 1 Pa is nonsense
    "oil.rho_oil": Range(100.0, 5000.0, True, True),
    "oil.nu": POS, "oil.P_sat": PRESSURE, "oil.P_vap": PRESSURE, "oil.chi": Range(0.0, 1.0, lo_incl=True),
    "oil.Gamma": Range(1.0, 2.0, True, True), "oil.P_0": PRESSURE, "oil.T": TEMPERATURE,
    "third_tube.E": Range(1e7, 1.2e12, True, True), "third_tube.nu_p": Range(0.0, 0.5),
    "third_tube.r_o": DIAMETER, "third_tube.r_i": DIAMETER,
    "top_mount.R": POS, "top_mount.p0": POS, "top_mount.p1": Range(), "top_mount.p2": POS,
    "top_mount.q0": POS, "top_mount.q1": Range(), "top_mount.q2": POS,
    "top_mount.k0": NONNEG, "top_mount.k1": POS, "top_mount.k2": POS,
    "top_mount.c0": NONNEG, "top_mount.c1": POS, "top_mount.c2": NONNEG,   # c1 > 0: THESIS-ERRATA 33
    **{f"{g}.{n}": r for g in ("piston_rebound", "base_compression") for n, r in _SHIM_RANGES.items()},
    **{f"{g}.{n}": r for g in ("piston_intake", "base_intake") for n, r in _INTAKE_RANGES.items()},
    "rod_friction.F_c": NONNEG, "rod_friction.F_s": NONNEG, "rod_friction.k_b": POS,
    "constants.P_atm": PRESSURE, "constants.P_ref": PRESSURE, "constants.T_ref": TEMPERATURE, "constants.rho_gas": POS,
    "constants.V_gas0": VOLUME, "constants.pt_r_i": DIAMETER, "constants.pt_r_o": DIAMETER,
    "constants.wall_ratio_third_tube": POS, "constants.A_bypass": upto(0.01, zero=True), "constants.Cq_bypass": COEF,
    "constants.p_transition": PRESSURE,
    "constants.zeta": Range(0.0, 3.141592653589793), "constants.k_contact": POS,
    "constants.zeta_contact": NONNEG, "constants.delta_contact": LIFT,
    **{f"constants.x_max_{v}": LIFT for v in VALVES},
    "constants.s2": NONNEG, "constants.c_comp": NONNEG, "constants.vd": POS, "constants.a_s": POS,
    "constants.alpha_s": POS, "constants.y_unit": LIFT, "constants.w_unit": POS,
}

# Ordered pairs: (smaller, larger, strict, why) — value(smaller) < value(larger).
ORDERED: tuple[tuple[str, str, bool, str], ...] = (
    ("geometry.D_R", "geometry.D_PT", True, "the rod must be narrower than the bore"),
    ("oil.P_vap", "oil.P_sat", True, "the vapour pressure lies below the gas saturation pressure"),
    ("constants.P_atm", "oil.P_0", True, "the precharge must exceed atmospheric pressure"),
    ("third_tube.r_i", "third_tube.r_o", True, "inner radius below outer radius"),
    ("constants.pt_r_i", "constants.pt_r_o", True, "inner radius below outer radius"),
    *((f"{g}.D_i", f"{g}.D_d", True, "inner diameter below disc diameter (eq. 4.21, 4.25)") for g in VALVES),
    *((f"{g}.D_h", f"{g}.D_d", True, "hole diameter below disc diameter (eq. 4.22)") for g in INTAKE_VALVES),
    ("rod_friction.F_c", "rod_friction.F_s", False, "Coulomb friction does not exceed static friction (eq. 4.41)"),
)

# Sums that must be positive (denominators of the model equations).
POSITIVE_SUMS: tuple[tuple[tuple[str, ...], str], ...] = (
    (("top_mount.c0", "top_mount.c2"), "denominator of eq. 4.34"),
)


EFFECT_PARAMETERS.update({
    "piston_leakage.gap": ("m", LIFT),
    "piston_leakage.length": ("m", LENGTH),
    "active_valve_lag.tau": ("s", POS),
    "aeration.alpha0": ("-", Range(0.0, 0.5, True, True)),
    "aeration.n": ("-", Range(1.0, 1.4, True, True)),
    "aeration.H": ("-", Range(0.0, 0.5, True, True)),
    "aeration.tau_rel": ("s", POS),
    "aeration.tau_dis": ("s", POS),
    "valve_friction_current.F0": ("N", NONNEG),
    "valve_friction_current.F1": ("N", NONNEG),
    "valve_friction_current.I_1": ("A", POS),
    "valve_friction_current.tau_s": ("s", POS),
    "valve_friction_current.A_spool": ("m^2", AREA),
    "valve_friction_current.dp_reg": ("Pa", PRESSURE),
    "oil_thermal.C_th": ("J/K", POS),
    "oil_thermal.hA": ("W/K", NONNEG),
    "oil_thermal.b_nu": ("1/K", NONNEG),
    "oil_thermal.c_K": ("1/K", Range(0.0, 0.02, True, True)),
    "oil_thermal.beta_T": ("1/K", Range(0.0, 0.005, True, True)),
    "rod_friction_asymmetric.a": ("-", Range(-0.95, 0.95, True, True)),
    "rod_friction_asymmetric.v_reg": ("m/s", POS),
    "top_mount_backlash.delta": ("m", upto(0.05, zero=True)),
    "top_mount_backlash.eps": ("m", LIFT),
    "seal_friction_pressure.k_p": ("N/Pa", NONNEG),
    "seal_friction_pressure.p_reg": ("Pa", PRESSURE),
    "fixture_resonance.f_n": ("Hz", Range(50.0, 1e4, True, True)),
    "fixture_resonance.zeta": ("-", Range(0.0, 1.0, False, True)),
    "active_valve_driver.tau_d": ("s", POS),
    "active_valve_driver.rate_max": ("A/s", POS),
    "active_valve_driver.tau_e": ("s", POS),
    "gas_release.tau_rel": ("s", POS),
    "gas_release.tau_dis": ("s", POS),
})
