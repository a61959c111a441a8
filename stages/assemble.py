"""DVC stage `assemble@<case>`: baseline + the case's variant + the fitted
overlays (its valves, compliance, its top mount) ->
results/approach1/designs/<case>.yaml."""

from _common import CONF, OUT, baseline, read_overlay, stage
from dampertwin.variants import TOP_MOUNTS, VALVE_DESIGNS, load_variant


def overlays_for(case: str) -> list:
    """The fit overlays a design case uses, in application order."""
    paths = []
    for valve in ("piston_rebound", "piston_intake", "base_compression", "base_intake"):
        vd = next((n for n, (v, c) in VALVE_DESIGNS.items() if v == valve and c == case), valve)
        paths.append(OUT / "valves" / vd / "overlay.yaml")
    paths.append(OUT / "compliance" / "overlay.yaml")
    tm = next((n for n, c in TOP_MOUNTS.items() if c == case), "baseline")
    paths.append(OUT / "topmount" / tm / "overlay.yaml")
    return paths


def main(case: str) -> None:
    d = load_variant(CONF / "variant" / f"{case}.yaml").apply(baseline())
    for p in overlays_for(case):
        d = d.with_overrides(read_overlay(p), source=p)
    d.dump(OUT / "designs" / f"{case}.yaml")


if __name__ == "__main__":
    stage(main, "assemble")
