"""Parsing and checking the effect switches (``effects:``) and the
parameters of the optional effects (``effect_parameters:``)."""

from __future__ import annotations

import math

from .entries import TEXT_FIELDS, EffectParameter, check_fields, check_strings
from .parse_params import _is_num
from .schema import EFFECT_NEEDS, EFFECT_PARAMETERS, EFFECTS

EFFECT_PARAM_FIELDS = ("name", "effect", "symbol", "description", "type", "value", "unit", "source", "typical")
EFFECT_PARAM_TYPES = ("C", "F")


def _parse_effects(eff, where, errors) -> dict[str, bool]:
    out: dict[str, bool] = {}
    if not isinstance(eff, dict):
        errors.append(f"{where}: 'effects' must be a mapping of switch -> true/false")
        return out
    for k, v in eff.items():
        if k not in EFFECTS:
            errors.append(f"{where}: effects.{k}: unknown effect switch; expected one of {', '.join(EFFECTS)}")
        elif not isinstance(v, bool):
            errors.append(f"{where}: effects.{k}: value {v!r} must be true or false")
        else:
            out[k] = v
    for k in EFFECTS:
        if k not in eff:
            errors.append(f"{where}: effects.{k}: missing switch (expected true or false)")
    for k, need in EFFECT_NEEDS.items():
        if out.get(k) and out.get(need) is False:
            errors.append(f"{where}: effects.{k}: true, but it modifies effects.{need}, which is false (it would "
                          f"do nothing); expected effects.{need}: true or effects.{k}: false")
    return {k: out[k] for k in EFFECTS if k in out}


def _parse_effect_parameters(items, effects, where, errors) -> dict[str, EffectParameter]:
    """The optional ``effect_parameters:`` list: each entry's effect and name
    declared in schema.EFFECT_PARAMETERS, SI unit, type C (bounds required,
    value and typical inside) or F (bounds optional), physical range."""
    out: dict[str, EffectParameter] = {}
    if not isinstance(items, list):
        errors.append(f"{where}: 'effect_parameters' must be a list of entries")
        return out
    for idx, item in enumerate(items):
        if not isinstance(item, dict):
            errors.append(f"{where}: effect_parameters[{idx}]: expected a mapping, got {type(item).__name__}")
            continue
        eff, nm = item.get("effect"), item.get("name")
        key = f"{eff}.{nm}"
        label = f"{where}: effect parameter {key!r}"
        if not isinstance(eff, str) or eff not in EFFECTS:
            errors.append(f"{label}: unknown effect {eff!r}; expected one of {', '.join(EFFECTS)}")
            continue
        if key not in EFFECT_PARAMETERS:
            known = [k.split('.', 1)[1] for k in EFFECT_PARAMETERS if k.startswith(eff + ".")]
            errors.append(f"{label}: unknown parameter {nm!r} of effect {eff!r}; expected one of {', '.join(known) or '(none)'}")
            continue
        if key in out:
            errors.append(f"{label}: duplicated")
            continue
        n_err = len(errors)
        check_fields(item, EFFECT_PARAM_FIELDS, label, errors, optional=("bounds",))
        check_strings(item, TEXT_FIELDS, label, errors)
        unit_decl, rng = EFFECT_PARAMETERS[key]
        ptype = item.get("type")
        if "type" in item and ptype not in EFFECT_PARAM_TYPES:
            errors.append(f"{label}: type {ptype!r}; effect parameters are C (calibrated, with bounds) or F (fixed)")
        if "unit" in item and item["unit"] != unit_decl:
            errors.append(f"{label}: unit {item['unit']!r}; expected the SI unit {unit_decl!r}")
        vals = {}
        for k in ("value", "typical"):
            v = item.get(k)
            if k not in item:
                continue
            if not _is_num(v) or not math.isfinite(v):
                errors.append(f"{label}: {k} {v!r} is not a finite number (in {unit_decl})")
            elif not rng.contains(v):
                errors.append(f"{label}: {k} {v!r}; expected {rng.describe()} {unit_decl}")
            else:
                vals[k] = float(v)
        bounds = item.get("bounds")
        if bounds is None:
            if ptype == "C":
                errors.append(f"{label}: calibrated (C) effect parameter has no bounds; expected [lower, upper] in {unit_decl}")
        elif not (isinstance(bounds, list) and len(bounds) == 2 and all(_is_num(b) and math.isfinite(b) for b in bounds)):
            errors.append(f"{label}: bounds must be [lower, upper] (two finite numbers), got {bounds!r}")
            bounds = None
        else:
            lo, hi = float(bounds[0]), float(bounds[1])
            bounds = (lo, hi)
            if not lo < hi:
                errors.append(f"{label}: bounds lower {lo!r} >= upper {hi!r}")
            elif not (rng.contains(lo) and rng.contains(hi)):
                errors.append(f"{label}: bounds [{lo!r}, {hi!r}] must lie inside the physical range {rng.describe()} {unit_decl}")
            else:
                for k, v in vals.items():
                    if not lo <= v <= hi:
                        errors.append(f"{label}: {k} {v!r} outside bounds [{lo!r}, {hi!r}] {unit_decl}")
        if len(errors) == n_err:
            out[key] = EffectParameter(name=nm, effect=eff, symbol=item["symbol"], description=item["description"],
                                       type=ptype, value=vals["value"], unit=unit_decl, source=item["source"],
                                       typical=vals["typical"], bounds=bounds)
    for eff, on in effects.items():
        if on:
            missing = [k for k in EFFECT_PARAMETERS if k.startswith(eff + ".") and k not in out
                       and not any(isinstance(i, dict) and f"{i.get('effect')}.{i.get('name')}" == k for i in items)]
            if missing:
                errors.append(f"{where}: effects.{eff} is on but its parameter(s) {', '.join(missing)} are not "
                              f"declared in effect_parameters")
    return out
