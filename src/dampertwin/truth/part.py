"""The real part behind a design case, as the lab's truth: the truth's
inputs from the case's drawings (params.nominal), a lab sample's truth
values and effect switches, the design variant's change carried over to
the truth's own drawings, and the part as built (params.derive).

A design variant changes what the design file describes (a stiffer mount,
a softer shim stack, another active valve's datasheet). The truth's
counterpart is a change of its parts: shim thickness scaled so the stack's
initial stiffness changes as the design's (stiffness ~ t^3), the coil
springs' rates, the rubber's moduli, and for another valve's datasheet the
solenoid force, main spring and bleed scaled as the datasheet's crack
pressure, slope and bleed flow change.
"""

from __future__ import annotations

import math

import numpy as np

from .params import INTAKES, SHIMS, TruthParameterError, check_effects, check_values, derive, nominal


def _initial_slope(g: dict) -> float:
    """Documented initial stiffness of a valve's spring [N/m] (design file)."""
    return float(g["a"] * g["b"] + g["c"] * g["d"])


def _map_features(m) -> tuple[float, float, float]:
    """(bleed flow at the smallest dp > 0, crack pressure and slope above it
    at the largest current) of a P/Q datasheet map."""
    dps, cur, Q = np.asarray(m.dps, float), np.asarray(m.currents, float), np.asarray(m.flow, float)
    q = Q[np.argmax(cur)]  # flow[i, j]: currents[i], dps[j]
    bleed = float(q[1])
    top = slice(len(dps) - 3, len(dps))
    slope = float(np.polyfit(dps[top], q[top], 1)[0])
    crack = float(dps[-1] - q[-1] / slope)
    return bleed, crack, slope


def variant_values(base, case) -> dict:
    """Truth inputs a design variant changes (``case`` against ``base``)."""
    v = {}
    ref = nominal(base)
    for s in SHIMS:
        r = _initial_slope(case.group(s)) / _initial_slope(base.group(s))
        if r != 1.0:
            v[f"{s}.t1"] = ref[f"{s}.t1"] * r ** (1 / 3)
            v[f"{s}.t2"] = ref[f"{s}.t2"] * r ** (1 / 3)
    for s in INTAKES:
        r = _initial_slope(case.group(s)) / _initial_slope(base.group(s))
        if r != 1.0:
            v[f"{s}.K_S"] = ref[f"{s}.K_S"] * r
    tb, tc = base.group("top_mount"), case.group("top_mount")
    if tc["F_LD"] != tb["F_LD"] or tc["k0"] != tb["k0"]:
        r_lin = tc["F_LD"][0] / tb["F_LD"][0]
        r3 = tc["F_LD"][2] / tb["F_LD"][2] if tb["F_LD"][2] else r_lin
        v["mount.K_E"] = ref["mount.K_E"] * r_lin
        v["mount.K_E3"] = ref["mount.K_E3"] * r3
        for k in ("K_1", "K_2", "K_3"):
            v[f"mount.{k}"] = ref[f"mount.{k}"] * tc["k0"] / tb["k0"]
    if base.pq_map is None or case.pq_map is None:  # a passive architecture: no active valve's datasheet
        return v
    fb, fc = _map_features(base.pq_map), _map_features(case.pq_map)
    if fb != fc:
        v["active_valve.A_B"] = ref["active_valve.A_B"] * fc[0] / fb[0]
        v["active_valve.F_S"] = ref["active_valve.F_S"] * fc[1] / fb[1]
        v["active_valve.F_P0"] = ref["active_valve.F_P0"] * fc[1] / fb[1]
        v["active_valve.K_M"] = ref["active_valve.K_M"] * fb[2] / fc[2]
    return v


PLAUSIBLE_RATIO = 100.0  # a real part's value lies within this factor of its drawing (a unit mix-up: 1e3 or more)


def _implausible(key: str, value, nominal_value) -> str:
    """'' or what is wrong with a sample's value against the nominal part's:
    the same sign and within PLAUSIBLE_RATIO of it (a switch or a value whose
    nominal is 0 or not a number is not judged)."""
    if not isinstance(nominal_value, (int, float)) or isinstance(nominal_value, bool) or nominal_value == 0 \
            or not math.isfinite(nominal_value) or not isinstance(value, (int, float)):
        return ""
    r = value / nominal_value
    if r <= 0:
        return f"{key}: {value!r}; the nominal part's is {nominal_value:.4g}: expected the same sign"
    if not 1.0 / PLAUSIBLE_RATIO <= r <= PLAUSIBLE_RATIO:
        return (f"{key}: {value!r} is {r:.3g}x the nominal part's {nominal_value:.4g}: expected a real part's "
                f"value within {PLAUSIBLE_RATIO:g}x of its drawing (a unit?)")
    return ""


def build(case, base, truth: dict | None = None, as_built_seed: int | None = None, P0: float | None = None,
          where: str = "truth"):
    """(parameter vector, rest dict {P0, V_gas0, T}, inputs) of the real part
    behind design ``case`` (``base``: the nominal design it varies). ``truth``:
    a sample's ``{values, effects}``; ``as_built_seed`` None: exactly the
    drawings; ``P0``: the gas fill (default the design's)."""
    truth = truth or {}
    values, effects = dict(truth.get("values", {})), dict(truth.get("effects", {}))
    check_values(values, f"{where}.values")
    check_effects(effects, f"{where}.effects")
    v = nominal(case)
    implausible = [_implausible(k, x, v.get(k)) for k, x in values.items()]
    implausible = [m for m in implausible if m]
    if implausible:
        raise TruthParameterError("; ".join(f"{where}.values.{m}" for m in implausible))
    v.update(values)
    v.update(variant_values(base, case))
    if P0 is not None:
        v["P0"] = float(P0)
    p = derive(v, effects, as_built_seed)
    return p, {"P0": v["P0"], "V_gas0": v["V_gas0"], "T": v["T"]}, v
