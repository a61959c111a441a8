"""Clicker adjusters of a design: the design's ``adjusters:`` table and its
``setting:`` (docs/reference/design-schema.md, "Adjusters").

An adjuster moves one table-5.1 parameter of one valve block (a bleed area
``A_bleed`` [m^2] or a preload ``F_preload`` [N]) through a list of clicks::

    adjusters:
      rebound:     {valve: piston_rebound,   parameter: A_bleed,   unit: m^2, clicks: [...], source: '...'}
      compression: {valve: base_compression, parameter: F_preload, unit: N,   clicks: [...], source: '...'}
    setting: {rebound: 3, compression: 5}

Clicks are counted out from fully closed ("full hard"), as on a dyno sheet:
click 0 is the hardest setting and each click out is softer, so a bleed
area rises strictly with the click number and a preload falls strictly.

One source of truth: the design's value of the moved parameter (its
``parameters:`` entry) *is* the setting. It must equal one of the clicks;
the optional ``setting:`` only names that click and must agree with it
(a mismatch is an error, never a silent override). ``Design.at_setting``
moves the parameters to other clicks through ``Design.with_overrides``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from .entries import check_fields
from .schema import PARAMETERS, RANGES, VALVES

ADJUSTER_NAMES = ("rebound", "compression")
ADJUSTER_FIELDS = ("valve", "parameter", "unit", "clicks", "source")
# parameter -> direction of its clicks (+1: rises with each click out, -1: falls): softer with each click out
ADJUSTABLE = {"A_bleed": +1, "F_preload": -1}
_SPECS = {f"{s.group}.{s.name}": s for s in PARAMETERS}


@dataclass(frozen=True)
class Adjuster:
    """One clicker: ``clicks[k]`` is the SI value (``unit``) of ``valve.parameter``
    at click k counted out from fully closed (click 0 = hardest)."""

    name: str
    valve: str
    parameter: str
    unit: str
    clicks: tuple[float, ...]
    source: str

    @property
    def key(self) -> str:
        """The moved parameter as ``"group.name"`` (e.g. ``"piston_rebound.A_bleed"``)."""
        return f"{self.valve}.{self.parameter}"

    @property
    def no(self) -> int:
        """Table-5.1 number of the moved parameter."""
        return _SPECS[self.key].no


def _num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _index(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _parse_one(name: str, item: Any, label: str, errors: list[str]) -> Adjuster | None:
    """One ``adjusters.<name>`` entry; problems appended to ``errors`` (file and key named)."""
    if not isinstance(item, dict):
        errors.append(f"{label}: expected a mapping with {', '.join(ADJUSTER_FIELDS)}, got {type(item).__name__}")
        return None
    n0 = len(errors)
    check_fields(item, ADJUSTER_FIELDS, label, errors)
    valve, par = item.get("valve"), item.get("parameter")
    if "valve" in item and valve not in VALVES:
        errors.append(f"{label}.valve: {valve!r}; expected one of {', '.join(VALVES)}")
    elif "parameter" in item and (par not in ADJUSTABLE or f"{valve}.{par}" not in _SPECS):
        has = [p for p in ADJUSTABLE if f"{valve}.{p}" in _SPECS]
        errors.append(f"{label}.parameter: {par!r}; an adjuster on {valve!r} moves one of {', '.join(has)}")
    if "source" in item and not isinstance(item["source"], str):
        errors.append(f"{label}.source: must be a string")
    if len(errors) > n0:
        return None
    spec = _SPECS[f"{valve}.{par}"]
    if item["unit"] != spec.unit:
        errors.append(f"{label}.unit: {item['unit']!r}; expected the SI unit {spec.unit!r} of no. {spec.no} "
                      f"({spec.group}.{spec.name})")
    clicks = item["clicks"]
    if not isinstance(clicks, list) or not clicks or not all(_num(c) for c in clicks):
        errors.append(f"{label}.clicks: expected a non-empty list of finite numbers in {spec.unit}, got {clicks!r}")
        return None
    rng = RANGES[spec.group + "." + spec.name]
    bad = [c for c in clicks if not rng.contains(c)]
    if bad:
        errors.append(f"{label}.clicks: {bad[0]!r} {spec.unit}; expected {rng.describe()} (physical range of "
                      f"{spec.group}.{spec.name})")
    sign = ADJUSTABLE[par]
    if any(not sign * (b - a) > 0 for a, b in zip(clicks, clicks[1:])):
        way = "rise" if sign > 0 else "fall"
        errors.append(f"{label}.clicks: {clicks!r}; expected values that {way} strictly with the click number "
                      f"(click 0 = fully closed, each click out softer)")
    if len(errors) > n0:
        return None
    return Adjuster(name, valve, par, spec.unit, tuple(float(c) for c in clicks), item["source"])


def parse_adjusters(items: Any, setting: Any, params: Mapping, where: str,
                    errors: list[str]) -> dict[str, Adjuster]:
    """The design's ``adjusters:`` table checked against its parsed ``params``
    (no. -> Parameter) and its optional ``setting:``; problems appended to
    ``errors``, each naming ``where`` and the key."""
    if items is None:
        if setting is not None:
            errors.append(f"{where}: setting: given but the design has no 'adjusters:' table")
        return {}
    if not isinstance(items, dict) or not items:
        errors.append(f"{where}: adjusters: expected a mapping of {' / '.join(ADJUSTER_NAMES)} -> "
                      f"{{{', '.join(ADJUSTER_FIELDS)}}}, got {items!r}")
        return {}
    out: dict[str, Adjuster] = {}
    for name, item in items.items():
        label = f"{where}: adjusters.{name}"
        if name not in ADJUSTER_NAMES:
            errors.append(f"{label}: unknown adjuster; expected one of {', '.join(ADJUSTER_NAMES)}")
            continue
        adj = _parse_one(name, item, label, errors)
        if adj is None:
            continue
        other = next((a for a in out.values() if a.key == adj.key), None)
        if other is not None:
            errors.append(f"{label}: moves {adj.key}, which adjusters.{other.name} moves already")
            continue
        out[name] = adj
    _check_setting(out, set(items), setting, params, where, errors)
    return out


def _check_setting(adjusters: dict[str, Adjuster], declared: set, setting: Any, params: Mapping, where: str,
                   errors: list[str]) -> None:
    """Each moved parameter's value is one of its clicks (inside its bounds if
    calibrated) and ``setting:`` names that click."""
    if setting is not None and not isinstance(setting, dict):
        errors.append(f"{where}: setting: expected a mapping adjuster -> click number, got {setting!r}")
        setting = None
    setting = setting or {}
    for name in setting:
        if name not in declared:
            errors.append(f"{where}: setting.{name}: no such adjuster; the design's adjusters are "
                          f"{', '.join(map(str, declared))}")
    for name, adj in adjusters.items():
        label = f"{where}: adjusters.{name}"
        p = params.get(adj.no)
        if p is None:
            continue  # the parameter itself is invalid: reported by the parameter checks
        if p.bounds is not None:
            out = [c for c in adj.clicks if not p.bounds[0] <= c <= p.bounds[1]]
            if out:
                errors.append(f"{label}.clicks: {out[0]!r} {adj.unit} outside the bounds [{p.bounds[0]!r}, "
                              f"{p.bounds[1]!r}] of no. {adj.no} ({adj.key})")
        at = adj.clicks.index(p.value) if p.value in adj.clicks else None
        if name in setting:
            k = setting[name]
            if not _index(k) or not 0 <= k < len(adj.clicks):
                errors.append(f"{where}: setting.{name}: {k!r}; expected a click number 0 .. {len(adj.clicks) - 1} "
                              f"(0 = fully closed)")
            elif k != at:
                errors.append(f"{where}: setting.{name}: click {k} is {adj.clicks[k]!r} {adj.unit}, but no. {adj.no} "
                              f"({adj.key}) has the value {p.value!r}; expected them equal (the parameter's value "
                              f"is the setting: change both, or use Design.at_setting)")
        elif at is None:
            errors.append(f"{label}: no. {adj.no} ({adj.key}) = {p.value!r} {adj.unit} is none of the clicks "
                          f"{list(adj.clicks)!r}; expected the value of one click (the design's setting; "
                          f"adjusters.without_adjusters frees the value, e.g. to calibrate one setting)")


def current_setting(design) -> dict[str, int]:
    """The design's click per adjuster (the click equal to the moved parameter's value)."""
    return {n: a.clicks.index(design[a.key]) for n, a in design.adjusters.items()}


def adjusters_doc(design) -> dict:
    """The ``adjusters:`` and ``setting:`` sections of a design's YAML (empty without adjusters)."""
    if not design.adjusters:
        return {}
    table = {n: {"valve": a.valve, "parameter": a.parameter, "unit": a.unit, "clicks": list(a.clicks),
                 "source": a.source} for n, a in design.adjusters.items()}
    return {"adjusters": table, "setting": current_setting(design)}


def setting_overrides(design, setting: Any, where: str) -> dict[str, float]:
    """``{"group.name": click value}`` for ``setting`` (adjuster -> click number);
    DesignError naming ``where`` and the key for an unknown adjuster or a click
    outside the table."""
    from .description import DesignError

    if not isinstance(setting, Mapping):
        raise DesignError([f"{where}: setting: expected a mapping adjuster -> click number, got {setting!r}"])
    errors, out = [], {}
    for name, k in setting.items():
        adj = design.adjusters.get(name)
        if adj is None:
            errors.append(f"{where}: setting.{name}: design {design.name!r} has no such adjuster; expected "
                          + (f"one of {', '.join(design.adjusters)}" if design.adjusters else
                             "none (the design has no 'adjusters:' table)"))
        elif not _index(k) or not 0 <= k < len(adj.clicks):
            errors.append(f"{where}: setting.{name}: click {k!r}; expected a click number 0 .. "
                          f"{len(adj.clicks) - 1} (0 = fully closed) of adjusters.{name}")
        else:
            out[adj.key] = adj.clicks[k]
    if errors:
        raise DesignError(errors)
    return out


def at_setting(design, setting: Mapping[str, int], source: str | None = None):
    """``design`` with its adjusters at ``setting`` (adjuster -> click number;
    adjusters left out keep their click), through ``Design.with_overrides``."""
    where = str(source) if source is not None else (str(design.path) if design.path else "<setting>")
    overrides = setting_overrides(design, setting, where)
    if all(design[k] == v for k, v in overrides.items()):
        return design
    return design.with_overrides(overrides, source=source)


def without_adjusters(design):
    """``design`` without its ``adjusters:`` table (the parameter values as they are): a
    design whose moved parameters may leave the clicks, e.g. to calibrate one setting."""
    from pathlib import Path

    from .description import _from_doc

    if not design.adjusters:
        return design
    doc = design._doc(design.path.parent if design.path else None)
    doc.pop("adjusters"), doc.pop("setting")
    return _from_doc(doc, design.path, base_dir=design.path.parent if design.path else Path.cwd(),
                     known_map=design.pq_map, map_dirs=design.map_dirs)


def record_setting(meta: Mapping, where: str = "record") -> dict[str, int] | None:
    """The ``setting`` a record's metadata names (None when it names none); DesignError
    naming ``where`` when it is not a mapping of adjuster -> click number."""
    from .description import DesignError

    s = meta.get("setting") if isinstance(meta, Mapping) else None
    if s is None:
        return None
    if not isinstance(s, Mapping) or not all(isinstance(n, str) and _index(k) for n, k in s.items()):
        raise DesignError([f"{where}: metadata 'setting': {s!r}; expected a mapping adjuster -> click number"])
    return dict(s)


def design_for_record(design, meta: Mapping, where: str = "record"):
    """The design at the setting the record's metadata names (``design`` itself when
    it names none); DesignError naming ``where`` when the design has no adjuster of
    that name or the click lies outside its table."""
    s = record_setting(meta, where)
    if s is None:
        return design
    base = str(design.path) if design.path else f"design {design.name!r}"
    return at_setting(design, s, source=f"{where} (setting of the record, on {base})")


def format_adjusters(design) -> list[str]:
    """Lines of a readable adjuster table (empty without adjusters); ``>`` marks the design's click."""
    if not design.adjusters:
        return []
    now = current_setting(design)
    lines = ["adjusters (click 0 = fully closed, counted out):"]
    for n, a in design.adjusters.items():
        cells = [f"{'>' if k == now[n] else ' '}{k}:{c:.4g}" for k, c in enumerate(a.clicks)]
        lines.append(f"  {n}: {a.key} (no. {a.no}) [{a.unit}], {len(a.clicks)} clicks, at click {now[n]}")
        lines.append("    " + " ".join(cells))
    return lines


__all__ = ["ADJUSTER_NAMES", "ADJUSTABLE", "Adjuster", "parse_adjusters", "adjusters_doc", "current_setting",
           "at_setting", "setting_overrides", "without_adjusters", "record_setting", "design_for_record", "format_adjusters"]
