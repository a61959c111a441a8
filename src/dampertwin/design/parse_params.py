"""Parsing and checking the numbered parameters (table 5.1) and the
constants of a design description; problems are appended to ``errors``
naming the file, the number and the name."""

from __future__ import annotations

import math
import os
from pathlib import Path

from . import architecture as _arch
from .entries import TEXT_FIELDS, Constant, Parameter, check_fields, check_strings
from .pqmap import PQMap, _find_map, _inside, _read_map
from .schema import BY_NUMBER, CONSTANT_TYPES, CONSTANTS, ORDERED, PARAMETERS, POSITIVE_SUMS, RANGES, SI_UNITS, TYPES

PARAM_FIELDS = ("no", "name", "symbol", "group", "description", "type", "value", "unit", "source")
CONST_FIELDS = ("name", "symbol", "description", "type", "value", "unit", "source")


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _fill_placeholders(arch: str, params: dict, constants: dict) -> None:
    """Add the numbers / constants of parts ``arch`` lacks that the file left out (design/architecture.py)."""
    nos, cons = _arch.placeholder_values(arch, {n: p.value for n, p in params.items()},
                                         {n: c.value for n, c in constants.items()})
    src = _arch.PLACEHOLDER.format(arch=arch)
    for no, v in nos.items():
        s = BY_NUMBER[no]
        params[no] = Parameter(no=no, name=s.name, symbol=s.name, group=s.group, description=src, type="F",
                               value=v, unit=s.unit, source=src)
    for name, v in cons.items():
        constants[name] = Constant(name, name, src, "F", float(v), CONSTANTS[name], src)


def _parse_parameters(items, where, base_dir, errors, known_map=None,
                      allowed_dirs=(), optional=()) -> tuple[dict[int, Parameter], PQMap | None]:
    out: dict[int, Parameter] = {}
    pq_map = None
    if not isinstance(items, list):
        errors.append(f"{where}: 'parameters' must be a list of parameter entries (nos. 1..105)")
        return out, None
    seen: dict[int, int] = {}
    for idx, item in enumerate(items):
        label = f"{where}: parameters[{idx}]"
        if not isinstance(item, dict):
            errors.append(f"{label}: expected a mapping, got {type(item).__name__}")
            continue
        no = item.get("no")
        nm = item.get("name")
        if "no" not in item:
            errors.append(f"{label} (name {nm!r}): missing number 'no' (expected an integer 1..105)")
            continue
        if not isinstance(no, int) or isinstance(no, bool) or no not in BY_NUMBER:
            errors.append(f"{label} no. {no!r} ({nm!r}): number outside 1..105 or not an integer")
            continue
        spec = BY_NUMBER[no]
        label = f"{where}: no. {no} ({spec.group}.{spec.name})"
        if no in seen:
            errors.append(f"{label}: duplicated number (entries {seen[no]} and {idx})")
            continue
        seen[no] = idx
        n_err = len(errors)
        check_fields(item, PARAM_FIELDS, label, errors, optional=("bounds",))
        if nm is not None and nm != spec.name:
            errors.append(f"{label}: name {nm!r} does not match table 5.1 no. {no}; expected {spec.name!r}")
        if item.get("group") is not None and item.get("group") != spec.group:
            errors.append(f"{label}: group {item.get('group')!r}; expected {spec.group!r}")
        check_strings(item, TEXT_FIELDS, label, errors)
        ptype = item.get("type")
        if "type" in item and ptype not in TYPES:
            errors.append(f"{label}: unknown type {ptype!r}; expected one of D, F, C, T")
        unit = item.get("unit")
        if "unit" in item:
            if not isinstance(unit, str) or unit not in SI_UNITS:
                errors.append(f"{label}: unit {unit!r} is unknown or not SI; expected {spec.unit!r}")
            elif unit != spec.unit:
                errors.append(f"{label}: unit {unit!r}; expected the SI unit {spec.unit!r}")
        value = item.get("value")
        bounds = item.get("bounds")
        if spec.kind == "table":
            if bounds is not None:
                errors.append(f"{label}: a P/Q map takes no bounds")
            if not isinstance(value, str) or not value:
                errors.append(f"{label}: value must be the file name of the P/Q map CSV, got {value!r}")
            else:
                map_path = Path(value) if os.path.isabs(value) else _find_map(value, base_dir, allowed_dirs)
                if known_map is not None:
                    pq_map = known_map
                elif _inside(map_path, allowed_dirs or (base_dir,)):
                    pq_map = _read_map(map_path, label, errors)
                else:
                    errors.append(f"{label}: P/Q map {value!r} lies outside the design's folder {str(base_dir)!r}; "
                                  f"expected a file name in that folder (other folders: load(..., map_dirs=[...]) "
                                  f"or DAMPERTWIN_MAP_DIRS)")
        else:
            value = _check_value(value, spec, label, errors)
            bounds = _check_bounds(bounds, ptype, value, spec, label, errors)
        if len(errors) == n_err:
            out[no] = Parameter(
                no=no, name=nm, symbol=item["symbol"], group=item["group"],
                description=item["description"], type=ptype, value=value, unit=unit,
                source=item["source"], bounds=bounds,
            )
    for no in BY_NUMBER:
        if no not in seen and no not in optional:
            s = BY_NUMBER[no]
            errors.append(f"{where}: no. {no} ({s.group}.{s.name}): missing number (table 5.1 has it)")
    return out, pq_map


def _check_value(value, spec, label, errors):
    if spec.kind == "vector":
        if not isinstance(value, list) or not value or not all(_is_num(v) for v in value):
            errors.append(f"{label}: value must be a non-empty list of numbers, got {value!r}")
            return None
        if not all(math.isfinite(v) for v in value):
            errors.append(f"{label}: value has a non-finite entry: {value!r}")
            return None
        return tuple(float(v) for v in value)
    if value is None:
        errors.append(f"{label}: missing value (expected a finite number in {spec.unit})")
        return None
    if not _is_num(value):
        errors.append(f"{label}: value {value!r} is not a number (expected a finite number in {spec.unit})")
        return None
    if not math.isfinite(value):
        errors.append(f"{label}: value {value!r} is not finite")
        return None
    return float(value)


def _check_bounds(bounds, ptype, value, spec, label, errors):
    if bounds is None:
        if ptype == "C":
            errors.append(f"{label}: calibrated (C) parameter has no bounds; expected [lower, upper] in {spec.unit}")
        return None
    if ptype != "C":
        errors.append(f"{label}: bounds given on a type-{ptype} parameter; only C parameters take bounds")
        return None
    if not isinstance(bounds, list) or len(bounds) != 2:
        errors.append(f"{label}: bounds must be [lower, upper], got {bounds!r}")
        return None
    lo, hi = bounds
    if spec.kind == "vector":
        n = len(value) if value is not None else None
        ok = all(isinstance(b, list) and (n is None or len(b) == n) and all(_is_num(x) and math.isfinite(x) for x in b) for b in (lo, hi))
        if not ok:
            errors.append(f"{label}: bounds must be [[lower...], [upper...]] with one finite number per coefficient")
            return None
        pairs = list(zip(lo, hi))
        out = (tuple(float(x) for x in lo), tuple(float(x) for x in hi))
    else:
        if not (_is_num(lo) and _is_num(hi) and math.isfinite(lo) and math.isfinite(hi)):
            errors.append(f"{label}: bounds must be two finite numbers, got {bounds!r}")
            return None
        pairs = [(lo, hi)]
        out = (float(lo), float(hi))
    for k, (a, b) in enumerate(pairs):
        if not a < b:
            errors.append(f"{label}: bounds lower {a!r} >= upper {b!r}")
            return None
    rng = RANGES.get(f"{spec.group}.{spec.name}")
    if rng is not None:
        for end, b in (("lower", out[0]), ("upper", out[1])):
            if not rng.contains(b):
                errors.append(f"{label}: {end} bound {b!r} {spec.unit}; expected the physical range {rng.describe()} "
                              f"(bounds [{out[0]!r}, {out[1]!r}] must lie inside it)")
                return None
    if value is not None:
        vals = value if spec.kind == "vector" else (value,)
        for v, (a, b) in zip(vals, pairs):
            if not a <= v <= b:
                errors.append(f"{label}: value {v!r} outside bounds [{a!r}, {b!r}] {spec.unit}")
                return None
    return out


def _parse_constants(items, where, errors, optional=()) -> dict[str, Constant]:
    out: dict[str, Constant] = {}
    if not isinstance(items, list):
        errors.append(f"{where}: 'constants' must be a list of entries")
        return out
    for idx, item in enumerate(items):
        if not isinstance(item, dict):
            errors.append(f"{where}: constants[{idx}]: expected a mapping")
            continue
        nm = item.get("name")
        label = f"{where}: constant {nm!r}"
        if not isinstance(nm, str) or nm not in CONSTANTS:
            errors.append(f"{label}: unknown constant; expected one of {', '.join(CONSTANTS)}")
            continue
        if nm in out:
            errors.append(f"{label}: duplicated")
            continue
        n_err = len(errors)
        check_fields(item, CONST_FIELDS, label, errors)
        if "type" in item and item["type"] not in CONSTANT_TYPES:
            errors.append(f"{label}: type {item['type']!r}; constants are D or F")
        unit = item.get("unit")
        if "unit" in item and unit != CONSTANTS[nm]:
            kind = "unknown or not SI" if not isinstance(unit, str) or unit not in SI_UNITS else "not the declared SI unit"
            errors.append(f"{label}: unit {unit!r} is {kind}; expected {CONSTANTS[nm]!r}")
        v = item.get("value")
        if "value" in item and (not _is_num(v) or not math.isfinite(v)):
            errors.append(f"{label}: value {v!r} is not a finite number")
        check_strings(item, TEXT_FIELDS, label, errors)
        if len(errors) == n_err:
            out[nm] = Constant(nm, item["symbol"], item["description"], item["type"], float(v), unit, item["source"])
    for nm in CONSTANTS:
        if nm not in out and nm not in optional and not any(isinstance(i, dict) and i.get("name") == nm for i in items):
            errors.append(f"{where}: constant {nm!r} missing (expected in {CONSTANTS[nm]})")
    return out


_KEY_NO = {f"{sp.group}.{sp.name}": sp.no for sp in PARAMETERS}


def _label(key: str) -> str:
    """'no. 3 (geometry.D_R)' or "constant 'P_atm'"."""
    if key.startswith("constants."):
        return f"constant {key.split('.', 1)[1]!r}"
    return f"no. {_KEY_NO[key]} ({key})"


def _check_physics(params: dict, constants: dict, where: str, errors: list[str]) -> None:
    """Physical ranges, ordered pairs and positive sums of schema.RANGES /
    ORDERED / POSITIVE_SUMS, on the entries that parsed."""
    vals: dict[str, float] = {}
    for no, p in params.items():
        if BY_NUMBER[no].kind == "scalar" and isinstance(p.value, float):
            vals[f"{p.group}.{p.name}"] = p.value
    for c in constants.values():
        vals[f"constants.{c.name}"] = c.value
    bad = set()
    for key, rng in RANGES.items():
        if key in vals and not rng.contains(vals[key]):
            errors.append(f"{where}: {_label(key)}: value {vals[key]!r}; expected {rng.describe()} {_unit(key)}")
            bad.add(key)
    for small, large, strict, why in ORDERED:
        if small in vals and large in vals and not bad & {small, large}:
            a, b = vals[small], vals[large]
            if not (a < b if strict else a <= b):
                errors.append(f"{where}: {_label(small)}: value {a!r}; expected {'<' if strict else '<='} "
                              f"{_label(large)} = {b!r} {_unit(small)} ({why})")
    for keys, why in POSITIVE_SUMS:
        if all(k in vals for k in keys) and not bad & set(keys) and not sum(vals[k] for k in keys) > 0:
            errors.append(f"{where}: {_label(keys[0])}: value {vals[keys[0]]!r}; expected "
                          f"{' + '.join(_label(k) for k in keys)} > 0 ({why})")


def _unit(key: str) -> str:
    if key.startswith("constants."):
        return CONSTANTS[key.split(".", 1)[1]]
    return BY_NUMBER[_KEY_NO[key]].unit
