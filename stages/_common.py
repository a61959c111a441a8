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
