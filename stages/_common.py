"""Shared helpers of the stage scripts (paths, config, overlays, atomic
writes). Stages are thin: parse config, call src/dampertwin, write outputs."""

from __future__ import annotations

import json
import os
from pathlib import Path

import yaml

from dampertwin.config import compose, repo_root
from dampertwin.design import Design, load, yaml_load

ROOT = repo_root(Path(__file__).parent)
CONF = ROOT / "conf"
OUT = ROOT / "results" / "approach1"
MEASURED = ROOT / "data" / "measured"


def params() -> dict:
    return yaml_load((ROOT / "params.yaml").read_text())


def config():
    """Composed config for the profile named in params.yaml."""
    return compose([f"profile={params()['profile']}"], ROOT)


def config_hash() -> str:
    """Hash of the composed configuration and params.yaml (carried by every artifact)."""
    import hashlib

    from omegaconf import OmegaConf

    blob = json.dumps({"config": OmegaConf.to_container(config(), resolve=True), "params": params()}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def baseline() -> Design:
    return load(CONF / "design" / "baseline.yaml")


def write_text(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)
    return path


def write_json(path: Path, obj) -> Path:
    return write_text(path, json.dumps(obj, indent=2, sort_keys=True) + "\n")


def write_overlay(path: Path, overrides: dict, meta: dict) -> Path:
    """A design overlay: the fitted values as design overrides, with provenance."""
    doc = {**meta, "overrides": {k: (list(v) if isinstance(v, (list, tuple)) else float(v)) for k, v in overrides.items()}}
    return write_text(path, yaml.safe_dump(doc, sort_keys=False))


def read_overlay(path: Path) -> dict:
    return yaml_load(path.read_text())["overrides"]


def seed_for(name: str) -> int:
    import zlib

    return int(config().seed + zlib.crc32(name.encode())) % (2**31)


def checkpoint(name: str) -> Path:
    """Per-generation GA checkpoint of a fit (kept only while the fit runs)."""
    return OUT / "checkpoints" / f"{name}.npz"


def write_fit(out: Path, res, meta: dict, unit: str, design_hash: str, best: dict | None = None,
              extra: dict | None = None) -> None:
    """A fit's outputs: overlay (fitted design values as design overrides;
    fitted ``sensor.*`` nuisance values go to the metrics, not the design),
    GA history (Parquet), metrics (objective at the start, GA best, after
    polish; failures) and the identifiability / uncertainty report
    (uncertainty.json, uncertainty.md)."""
    from dampertwin.io import write_frame

    meta = {**meta, "config_hash": config_hash()}
    best = res.best if best is None else best
    write_overlay(out / "overlay.yaml", {k: v for k, v in best.items() if not k.startswith("sensor.")}, meta)
    write_frame(out / "history.parquet",
                res.history.rename(columns={"best": f"best [{unit}]", "mean": f"mean [{unit}]"}),
                {**meta, "design_hash": design_hash})
    unc = dict(res.uncertainty)
    md = unc.pop("markdown", None)
    write_json(out / "metrics.json", {"objective_start": res.start_objective, "objective_best": res.best_objective,
                                      "objective_ga": res.objective_ga,
                                      "objective_polished": res.polish.get("objective_polished"),
                                      "improvement_pct": 100 * (1 - res.best_objective / res.start_objective),
                                      "failed_simulations": res.failed, "evaluations": res.evaluations,
                                      "nuisance": {k: v for k, v in best.items() if k.startswith("sensor.")},
                                      "polish": res.polish, "undetermined": unc.get("undetermined"),
                                      **(extra or {})})
    write_json(out / "uncertainty.json", {**unc, "objective": meta.get("objective")})
    write_text(out / "uncertainty.md", (md or "No uncertainty analysis (no polish configured).")
               .replace("# Identifiability and uncertainty", f"# Identifiability and uncertainty: {out.name}") + "\n")
