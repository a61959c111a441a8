"""Shared helpers of the stage scripts (paths, config, overlays, atomic
writes). Stages are thin: parse config, call src/dampertwin, write outputs."""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

import yaml

from dampertwin.config import compose, repo_root
from dampertwin.design import ConfigTextError, Design, load, yaml_load_file
from dampertwin.errors import UserError, run_main

ROOT = repo_root(Path(__file__).parent)
CONF = ROOT / "conf"
OUT = ROOT / "results" / "approach1"


def params() -> dict:
    doc = yaml_load_file(ROOT / "params.yaml")
    if not isinstance(doc, dict) or doc.get("profile") not in [p.stem for p in (CONF / "profile").glob("*.yaml")]:
        raise UserError(f"{ROOT / 'params.yaml'}: profile {doc.get('profile') if isinstance(doc, dict) else doc!r}; "
                        f"expected one of {sorted(p.stem for p in (CONF / 'profile').glob('*.yaml'))}")
    return doc


def stage(main, prog: str) -> None:
    """Run a stage's main(*argv): a user error is one line on stderr and exit
    2 (``--debug`` or DAMPERTWIN_DEBUG=1 adds the traceback); SIGTERM
    unwinds like Ctrl-C, so temporary outputs are removed."""
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    sys.exit(run_main(main, sys.argv[1:], prog=prog))


def choice(name: str, options, what: str) -> str:
    """``name`` if it is one of ``options``, else a UserError listing them."""
    if name not in options:
        raise UserError(f"unknown {what} {name!r}; expected one of {', '.join(options)}")
    return name


@contextmanager
def staged_dir(out: Path):
    """Build a stage's output folder in a temporary sibling and swap it in at
    the end: a failed or killed stage leaves no partial artifact folder (and
    the next run removes a temporary one a SIGKILL left behind)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    for stale in out.parent.glob(f".{out.name}.tmp*"):
        shutil.rmtree(stale, ignore_errors=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp", dir=out.parent))
    try:
        yield tmp
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def final_name(folder: Path) -> str:
    """The name a folder has once :func:`staged_dir` swaps it in (``.NAME.tmpXXXX`` -> ``NAME``): outputs
    written inside the temporary folder never carry its random name (same input, same bytes)."""
    import re

    m = re.fullmatch(r"\.(.+)\.tmp[^.]*", folder.name)
    return m.group(1) if m else folder.name


def design_values(best: dict) -> dict:
    """A fit's values without its nuisance parameters (``sensor.*``: the
    measurement chain, never design overrides)."""
    return {k: v for k, v in best.items() if not k.startswith("sensor.")}


def measured_dir() -> Path:
    """The measurement folder the stages read: params.yaml `measured`
    (default data/measured, the lab's output; e.g. data/own for your own)."""
    return ROOT / params().get("measured", "data/measured")



def config():
    """Composed config for the profile named in params.yaml."""
    return compose([f"profile={params()['profile']}"], ROOT)


HASHED_PARAMS = ("profile", "measured")  # params.yaml keys every stage that writes the hash declares


def config_hash() -> str:
    """Hash of the composed configuration and the params.yaml keys HASHED_PARAMS (carried by every
    artifact): only keys each hash-writing stage declares in dvc.yaml, so an undeclared key (e.g.
    `valve_map` for the valve fits) never changes an output behind DVC's back."""
    import hashlib

    from omegaconf import OmegaConf

    p = params()
    blob = json.dumps({"config": OmegaConf.to_container(config(), resolve=True),
                       "params": {k: p.get(k) for k in HASHED_PARAMS}}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def baseline() -> Design:
    return load(CONF / "design" / "baseline.yaml")


VALVE_MAPS = ("part", "datasheet")
PART_MAP = OUT / "activevalve" / "map.csv"  # stage activevalve_map's output


def valve_map() -> str:
    """params.yaml `valve_map`: which active-valve P/Q map (no. 52) the study's damper-level fits and
    designs use; `part` (the default) or `datasheet`."""
    v = params().get("valve_map", "part")
    if v not in VALVE_MAPS:
        raise UserError(f"{ROOT / 'params.yaml'}: valve_map {v!r}; expected one of {', '.join(VALVE_MAPS)}")
    return v


def study_design() -> Design:
    """The baseline design with the study's active-valve map: with `valve_map: part` the part's own map,
    built from its bench record by stage activevalve_map (PART_MAP, on the datasheet map's grid), in
    place of the datasheet map, before every fit whose test runs through the valve (a map error would
    otherwise be absorbed by the gas content, the bulk modulus or the valves); with `datasheet` the
    design's no. 52 as written (the thesis' approach 1: the supplier's map, fig. 6.2)."""
    if valve_map() == "datasheet":
        return baseline()
    if not PART_MAP.is_file():
        raise UserError(f"{PART_MAP}: not found; expected the part's active-valve map of stage activevalve_map "
                        f"(run `dvc repro activevalve_map`, or set valve_map: datasheet in params.yaml)")
    rel = PART_MAP.relative_to(ROOT).as_posix()
    d = load(CONF / "design" / "baseline.yaml", map_dirs=[PART_MAP.parent])
    part = d.with_overrides({"active_valve.pq_map": str(PART_MAP)}, source=rel).pq_map
    return d.with_pq_map(part, str(PART_MAP), f"measured: the part on its active-valve bench ({rel}, stage "
                         f"activevalve_map), in place of the datasheet map {d['active_valve.pq_map']}")


def write_text(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)
    return path


def write_json(path: Path, obj) -> Path:
    """Standard JSON (a non-finite number as null), sorted keys; a ``metrics.json`` carries the ``code_hash`` of the
    source that wrote it (dampertwin.provenance; checked by tests/test_repo.py)."""
    if path.name == "metrics.json" and isinstance(obj, dict):
        from dampertwin.provenance import with_code_hash

        obj = with_code_hash(obj)
    from dampertwin.io import json_safe

    return write_text(path, json.dumps(json_safe(obj), indent=2, sort_keys=True, allow_nan=False) + "\n")


def write_overlay(path: Path, overrides: dict, meta: dict) -> Path:
    """A design overlay: the fitted values as design overrides, with provenance."""
    doc = {**meta, "overrides": {k: (list(v) if isinstance(v, (list, tuple)) else float(v)) for k, v in overrides.items()}}
    return write_text(path, yaml.safe_dump(doc, sort_keys=False))


def read_overlay(path: Path) -> dict:
    if not path.is_file():
        raise UserError(f"{path}: fit overlay not found; expected the output of its fit stage (run dvc repro)")
    try:
        doc = yaml_load_file(path)
    except ConfigTextError as e:
        raise UserError(str(e)) from None
    if not isinstance(doc, dict) or not isinstance(doc.get("overrides"), dict):
        raise UserError(f"{path}: expected a mapping with an 'overrides' mapping of parameter -> value")
    return doc["overrides"]


def seed_for(name: str) -> int:
    import zlib

    return int(config().seed + zlib.crc32(name.encode())) % (2**31)


def checkpoint(name: str) -> Path:
    """Per-generation GA checkpoint of a fit (kept only while the fit runs)."""
    return OUT / "checkpoints" / f"{name}.npz"


def checkpoint_store(name: str):
    """The file store of :func:`checkpoint` (the GA saves its state there; it opens no file itself)."""
    from dampertwin.checkpoint import NpzStore

    return NpzStore(checkpoint(name))


def write_fit(out: Path, res, meta: dict, unit: str, design_hash: str, best: dict | None = None,
              extra: dict | None = None) -> None:
    """A fit's outputs: overlay (fitted design values as design overrides;
    fitted ``sensor.*`` nuisance values go to the metrics, not the design),
    GA history (Parquet), metrics (objective at the start, GA best, after
    polish; failures; the values that end on a search bound) and the identifiability / uncertainty report
    (uncertainty.json, uncertainty.md)."""
    from dampertwin.io import write_frame

    meta = {**meta, "config_hash": config_hash()}
    start, best_j = res.start_objective, res.best_objective
    improvement = 100 * (1 - best_j / start) if math.isfinite(start) and start > 0 else None
    best = res.best if best is None else best
    write_overlay(out / "overlay.yaml", design_values(best), meta)
    write_frame(out / "history.parquet",
                res.history.rename(columns={"best": f"best [{unit}]", "mean": f"mean [{unit}]"}),
                {**meta, "design_hash": design_hash})
    unc = dict(res.uncertainty)
    md = unc.pop("markdown", None)
    write_json(out / "metrics.json", {"objective_start": res.start_objective, "objective_best": res.best_objective,
                                      "objective_ga": res.objective_ga,
                                      "objective_polished": res.polish.get("objective_polished"),
                                      "improvement_pct": improvement,
                                      "failed_simulations": res.failed, "evaluations": res.evaluations,
                                      **({"failure_reasons": res.failures} if res.failures else {}),
                                      "nuisance": {k: v for k, v in best.items() if k.startswith("sensor.")},
                                      "polish": res.polish, "undetermined": unc.get("undetermined"),
                                      "bounds": {s.key: [s.lo, s.hi, s.scale] for s in res.specs},
                                      "bound_hits": res.bound_hits,
                                      **(extra or {})})
    write_json(out / "uncertainty.json", {**unc, "objective": meta.get("objective")})
    write_text(out / "uncertainty.md", (md or "No uncertainty analysis (no polish configured).")
               .replace("# Identifiability and uncertainty", f"# Identifiability and uncertainty: {final_name(out)}") + "\n")
