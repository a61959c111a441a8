"""Damper architectures a design may describe (design key ``architecture:``).

- ``triple_tube_semi_active`` (default): the thesis' damper (ch. 4): pressure
  tube, third (bypass) tube with the electronically controlled valve, reserve
  tube with gas; piston and base valves.
- ``twin_tube``: a passive twin-tube damper: the same pressure tube, piston
  valves and base (foot) valves, the reserve tube with gas; no third tube, no
  active valve (Dixon 2007, *The Shock Absorber Handbook*, 2nd ed., sec. 1.4).
- ``mono_tube``: a passive mono-tube damper: piston valves only; a floating
  piston separates the compression chamber from a gas chamber (Dixon 2007,
  sec. 1.4; Talbott & Starkey 2002, SAE 2002-01-3337). The piston's
  compression valve is the ``piston_intake`` block (a sprung disc over holes,
  eq. 4.22, 4.28); the gas is the reserve gas spring (``oil.P_0``,
  ``constants.V_gas0``).

The architectures share every submodel (chambers, valves, gas spring, rod
friction, top mount); the model's hub (``model/damper.py``) leaves out the
parts an architecture lacks. The table-5.1 numbers and constants of parts an
architecture lacks may be left out of its design file: the loader fills them
with placeholders (source ``PLACEHOLDER``) that are never simulated and not
written back by ``Design.dump``.
"""

from __future__ import annotations

import math

from .schema import BY_NUMBER

DEFAULT = "triple_tube_semi_active"
ARCHITECTURES = {  # name -> code read by the compiled model (layout parameter ARCH)
    "triple_tube_semi_active": 0,
    "twin_tube": 1,
    "mono_tube": 2,
}
DESCRIPTION = {
    "triple_tube_semi_active": "semi-active triple tube (thesis ch. 4): third tube with the active valve",
    "twin_tube": "passive twin tube: piston and base valves, reserve tube with gas",
    "mono_tube": "passive mono tube: piston valves, floating piston, gas chamber",
}
PLACEHOLDER = "placeholder: not part of a {arch} damper (never simulated)"

_THIRD_TUBE = (4, 16, 17, 18, 19)  # geometry.V_b, third_tube.E, nu_p, r_o, r_i
_ACTIVE_MAP = (52,)
_BASE_VALVES = tuple(range(69, 103))  # base_compression 69-86, base_intake 87-102
# numbers a design of the architecture may leave out
UNUSED_NUMBERS = {
    "triple_tube_semi_active": (),
    "twin_tube": _THIRD_TUBE + _ACTIVE_MAP,
    "mono_tube": _THIRD_TUBE + _ACTIVE_MAP + _BASE_VALVES,
}
_THIRD_TUBE_CONSTANTS = ("wall_ratio_third_tube", "A_bypass", "Cq_bypass")
UNUSED_CONSTANTS = {
    "triple_tube_semi_active": (),
    "twin_tube": _THIRD_TUBE_CONSTANTS,
    "mono_tube": _THIRD_TUBE_CONSTANTS + ("x_max_base_compression", "x_max_base_intake"),
}
# placeholder values [SI] of the third tube's numbers and constants: a closed,
# rigid-walled volume with no bypass (finite, inside the schema's ranges)
_FIXED_PLACEHOLDERS = {4: 1e-4, 16: 2.1e11, 17: 0.3, 18: 0.021, 19: 0.02}
_FIXED_CONSTANT_PLACEHOLDERS = {"wall_ratio_third_tube": 1.0, "A_bypass": 0.0, "Cq_bypass": 0.7}
# a left-out base valve takes the values of the piston valve of its kind (the
# same schema: shim stack 69-86 <- 34-51, intake disc 87-102 <- 53-68)
_COPY_FROM = {**{n: n - 35 for n in range(69, 87)}, **{n: n - 34 for n in range(87, 103)}}
_CONSTANT_COPY_FROM = {"x_max_base_compression": "x_max_piston_rebound", "x_max_base_intake": "x_max_piston_intake"}
# effects that act on the active valve: meaningless without one
ACTIVE_VALVE_EFFECTS = ("active_valve_lag", "valve_friction_current", "active_valve_driver")
# effects whose equations assume a reserve tube (none since the floating-piston balance carries the gas's heating)
NOT_IN_MONO_TUBE: tuple[str, ...] = ()


def parse(doc: dict, where: str, errors: list[str]) -> str:
    """The design's architecture (``DEFAULT`` when the key is absent)."""
    arch = doc.get("architecture", DEFAULT)
    if arch not in ARCHITECTURES:
        errors.append(f"{where}: architecture: {arch!r}; expected one of {', '.join(ARCHITECTURES)}")
        return DEFAULT
    return arch


def check_effects(arch: str, effects: dict, where: str, errors: list[str]) -> None:
    """Effects the architecture has no part for are errors, not silently ignored."""
    if arch == DEFAULT:
        return
    for e in ACTIVE_VALVE_EFFECTS:
        if effects.get(e):
            errors.append(f"{where}: effects.{e}: true, but a {arch} damper has no active valve; expected false")
    if arch == "mono_tube":
        for e in NOT_IN_MONO_TUBE:
            if effects.get(e):
                errors.append(f"{where}: effects.{e}: true is not supported for a mono_tube damper yet (the floating "
                              f"piston's gas balance does not carry the gas's heating); expected false")


def check_gas_volume(arch: str, values: dict[str, float], constants: dict[str, float], where: str,
                     errors: list[str]) -> None:
    """A passive damper's gas must take the rod's volume over the whole compression travel:
    V_gas0 > pi D_R^2 / 4 * l_c0 (else the gas would be compressed to nothing before the piston bottoms out).
    Not checked for the thesis' damper (its designs load as before)."""
    if arch == DEFAULT:
        return
    try:
        rod = math.pi * values["geometry.D_R"] ** 2 / 4.0 * values["geometry.l_c0"]
        v_gas = constants["V_gas0"]
    except KeyError:  # a missing entry is reported by the parser
        return
    if not v_gas > rod:
        errors.append(f"{where}: constant 'V_gas0': value {v_gas!r}; expected > the rod's swept volume over the "
                      f"compression travel, pi D_R^2 / 4 * l_c0 = {rod:.4g} m^3 (a {arch} damper's gas takes the "
                      f"rod's volume)")


def check_adjusters(arch: str, adjusters: dict, where: str, errors: list[str]) -> None:
    """An adjuster must move a valve the architecture has (a mono tube has no base valves)."""
    if arch != "mono_tube":
        return
    for name, a in adjusters.items():
        if a.valve.startswith("base_"):
            errors.append(f"{where}: adjusters.{name}.valve: {a.valve!r}, but a mono_tube damper has no base valves; "
                          f"expected piston_rebound or piston_intake (the piston's compression valve)")


def placeholder_values(arch: str, values: dict[int, object], constants: dict[str, float]) -> tuple[dict, dict]:
    """Values of the left-out numbers / constants of ``arch``: ({no: value}, {name: value}).
    ``values`` / ``constants`` are the ones the design gives."""
    nos, cons = {}, {}
    for no in UNUSED_NUMBERS[arch]:
        if no in values or BY_NUMBER[no].kind == "table":
            continue
        if no in _FIXED_PLACEHOLDERS:
            nos[no] = _FIXED_PLACEHOLDERS[no]
        elif _COPY_FROM.get(no) in values:
            nos[no] = values[_COPY_FROM[no]]
    for name in UNUSED_CONSTANTS[arch]:
        if name in constants:
            continue
        if name in _FIXED_CONSTANT_PLACEHOLDERS:
            cons[name] = _FIXED_CONSTANT_PLACEHOLDERS[name]
        elif _CONSTANT_COPY_FROM.get(name) in constants:
            cons[name] = constants[_CONSTANT_COPY_FROM[name]]
    return nos, cons


def is_placeholder(source: str, arch: str) -> bool:
    return arch != DEFAULT and source == PLACEHOLDER.format(arch=arch)
