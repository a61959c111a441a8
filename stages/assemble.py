"""DVC stage `assemble@<case>`: baseline + the case's variant + the fitted
overlays (its valves, compliance, its top mount) ->
results/approach1/designs/<case>.yaml, with its active valve's P/Q map
beside it (<case>_active_valve.csv: the part's own with params.yaml
`valve_map: part`, unless the case names another valve; a design file that
loads on its own)."""

import os
from pathlib import Path

from _common import CONF, OUT, ROOT, baseline, read_overlay, stage, study_design
from dampertwin.design import write_map
from dampertwin.errors import UserError
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


def map_name(case: str) -> str:
    """The file of a case's P/Q map beside its design."""
    return f"{case}_active_valve.csv"


def copy_source(d, variant: str | None = None) -> str:
    """No. 52's source line for the copy beside the design: how the map was found (the case's variant file when
    it names its own valve), and the repository file it copies."""
    f = Path(d["active_valve.pq_map"])
    f = Path(os.path.normpath(f if f.is_absolute() else CONF / "design" / f))  # relative: to the baseline design
    if not f.is_relative_to(ROOT):
        raise UserError(f"{f}: the active-valve map a study design copies must lie in the repository {ROOT}")
    how = f"{variant}: the case's own active valve" if variant else d.param("active_valve.pq_map").source
    return f"{how}; a copy of {f.relative_to(ROOT).as_posix()}"


def main(case: str) -> None:
    variant = load_variant(CONF / "variant" / f"{case}.yaml")
    base = baseline()
    own_valve = variant.apply(base).pq_map != base.pq_map  # the case names another valve: no bench record of it
    d = variant.apply(base if own_valve else study_design())
    for p in overlays_for(case):
        d = d.with_overrides(read_overlay(p), source=p)
    out = OUT / "designs"
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / f".{map_name(case)}.tmp{os.getpid()}"
    write_map(tmp, d.pq_map)
    os.replace(tmp, out / map_name(case))  # the map first: the design that names it is written last
    own = (CONF / "variant" / f"{case}.yaml").relative_to(ROOT).as_posix() if own_valve else None
    d = d.with_pq_map(d.pq_map, str(out / map_name(case)), copy_source(d, own))
    d.dump(out / f"{case}.yaml")


if __name__ == "__main__":
    stage(main, "assemble")
