"""Design cases (thesis table 6.5 rows): a variant names only what it changes
(design overrides and the active-valve current, a test condition)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from .design import ConfigTextError, Design, yaml_load_file
from .errors import UserError

VARIANT_KEYS = ("case", "row", "title", "current", "overrides")


class VariantError(UserError):
    """A design-case (variant) file is invalid; the message names the file."""


def check_current(current, design: Design, where: str) -> float:
    """The active-valve current [A] as a float inside the design's P/Q map
    range (never clamped silently); VariantError naming ``where`` otherwise."""
    lo, hi = float(design.pq_map.currents[0]), float(design.pq_map.currents[-1])
    if not isinstance(current, (int, float)) or isinstance(current, bool) or not math.isfinite(current):
        raise VariantError(f"{where}: current {current!r}; expected a finite number in A within the "
                           f"active-valve map [{lo:g}, {hi:g}] A")
    if not lo - 1e-12 <= current <= hi + 1e-12:
        raise VariantError(f"{where}: current {current!r} A outside the active-valve map [{lo:g}, {hi:g}] A "
                           f"(it would be clamped); expected a current the map covers")
    return float(current)


@dataclass(frozen=True)
class Variant:
    case: str
    row: int
    title: str
    current: float
    overrides: dict = field(default_factory=dict)
    path: str = field(default="<variant>", compare=False)

    def apply(self, design: Design) -> Design:
        """The design with this case's overrides; errors name the variant
        file; the current must lie in the (resulting) design's P/Q map."""
        d = design.with_overrides(self.overrides, source=self.path) if self.overrides else design
        check_current(self.current, d, self.path)
        return d


TABLE_ROWS = 10  # thesis table 6.5 has rows 1..10 (a variant's ``row``)


def variant_errors(doc, path) -> list[str]:
    """Every problem of a variant document (keys, case, row, title, current,
    overrides), each naming ``path`` and the key."""
    import difflib

    if not isinstance(doc, dict):
        return [f"{path}: expected a mapping with keys {', '.join(VARIANT_KEYS)}"]
    errors = []
    for k in VARIANT_KEYS:
        if k not in doc:
            errors.append(f"{path}: missing key {k!r}")
    for k in doc:
        if k not in VARIANT_KEYS:
            near = difflib.get_close_matches(str(k), VARIANT_KEYS, n=1)
            errors.append(f"{path}: unknown key {k!r}" + (f" (did you mean {near[0]!r}?)" if near else "")
                          + f"; expected {', '.join(VARIANT_KEYS)}")
    cur = doc.get("current")
    if "current" in doc and (not isinstance(cur, (int, float)) or isinstance(cur, bool) or not math.isfinite(cur)
                             or not cur > 0):
        errors.append(f"{path}: current {cur!r}; expected a positive finite number in A")
    row = doc.get("row")
    if "row" in doc and (not isinstance(row, int) or isinstance(row, bool) or not 1 <= row <= TABLE_ROWS):
        errors.append(f"{path}: row {row!r}; expected an integer 1..{TABLE_ROWS} (the row of thesis table 6.5)")
    for k in ("case", "title"):
        if k in doc and (not isinstance(doc[k], str) or not doc[k]):
            errors.append(f"{path}: {k} {doc[k]!r}; expected a non-empty string")
    if not isinstance(doc.get("overrides", {}), (dict, type(None))):
        errors.append(f"{path}: overrides must be a mapping of parameter -> value")
    return errors


def load_variant(path: str | Path) -> Variant:
    path = Path(path)
    try:
        doc = yaml_load_file(path)
    except ConfigTextError as e:
        raise VariantError(str(e)) from None
    errors = variant_errors(doc, path)
    if errors:
        raise VariantError(errors)
    return Variant(doc["case"], doc["row"], doc["title"], float(doc["current"]), dict(doc["overrides"] or {}),
                   str(path))


def load_variants(folder: str | Path) -> list[Variant]:
    """All variants of a folder, ordered by table row."""
    vs = [load_variant(p) for p in sorted(Path(folder).glob("*.yaml"))]
    return sorted(vs, key=lambda v: v.row)


# The eight flow-bench valve designs (thesis 6.2): the four baseline valves
# and the four lower-stiffness alternatives (table 6.5 rows 7-10).
VALVE_DESIGNS = {
    "piston_rebound": ("piston_rebound", None),
    "piston_intake": ("piston_intake", None),
    "base_compression": ("base_compression", None),
    "base_intake": ("base_intake", None),
    "piston_rebound_lower": ("piston_rebound", "lower_piston_rebound"),
    "piston_intake_lower": ("piston_intake", "lower_piston_intake"),
    "base_compression_lower": ("base_compression", "lower_base_compression"),
    "base_intake_lower": ("base_intake", "lower_base_intake"),
}
TOP_MOUNTS = {"baseline": None, "alternative": "alternative_top_mount"}
