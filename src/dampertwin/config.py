"""The composed Hydra configuration for stages and commands (Hydra's compose
API: no ``@hydra.main`` inside DVC stages)."""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

ROOT_MARKERS = ("dvc.yaml", "pyproject.toml")


def repo_root(start: str | Path | None = None) -> Path:
    """The repository root (the folder holding dvc.yaml), from ``start`` or cwd."""
    p = Path(start or Path.cwd()).resolve()
    for q in (p, *p.parents):
        if all((q / m).exists() for m in ROOT_MARKERS):
            return q
    raise FileNotFoundError(f"no dampertwin repository (with {', '.join(ROOT_MARKERS)}) above {p}")


def compose(overrides: list[str] | tuple[str, ...] = (), root: str | Path | None = None) -> DictConfig:
    """Compose conf/config.yaml with Hydra overrides (e.g. ``profile=ci``)."""
    from hydra import compose as h_compose
    from hydra import initialize_config_dir

    conf = repo_root(root) / "conf"
    with initialize_config_dir(config_dir=str(conf), version_base="1.3"):
        cfg = h_compose(config_name="config", overrides=list(overrides))
    OmegaConf.set_readonly(cfg, True)
    return cfg
