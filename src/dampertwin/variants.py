"""Design cases (thesis table 6.5 rows): a variant names only what it changes
(design overrides and the active-valve current, a test condition)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import yaml

from .design import Design, yaml_load

VARIANT_KEYS = ("case", "row", "title", "current", "overrides")


class VariantError(ValueError):
    pass


@dataclass(frozen=True)
class Variant:
    case: str
    row: int
    title: str
    current: float
    overrides: dict = field(default_factory=dict)

    def apply(self, design: Design) -> Design:
        return design.with_overrides(self.overrides) if self.overrides else design


def load_variant(path: str | Path) -> Variant:
    path = Path(path)
    try:
        doc = yaml_load(path.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise VariantError(f"{path}: cannot read variant: {e}") from None
    errors = []
    if not isinstance(doc, dict):
        raise VariantError(f"{path}: expected a mapping with keys {', '.join(VARIANT_KEYS)}")
    for k in VARIANT_KEYS:
        if k not in doc:
            errors.append(f"{path}: missing key {k!r}")
    for k in doc:
        if k not in VARIANT_KEYS:
            errors.append(f"{path}: unknown key {k!r}; expected {', '.join(VARIANT_KEYS)}")
    cur = doc.get("current")
    if not isinstance(cur, (int, float)) or isinstance(cur, bool) or not cur > 0:
        errors.append(f"{path}: current {cur!r}; expected a positive number in A")
    if not isinstance(doc.get("overrides", {}), dict):
        errors.append(f"{path}: overrides must be a mapping of parameter -> value")
    if errors:
        raise VariantError("\n".join(errors))
    return Variant(str(doc["case"]), int(doc["row"]), str(doc["title"]), float(cur), dict(doc["overrides"] or {}))


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
