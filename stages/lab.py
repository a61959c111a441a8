"""DVC stage `lab`: the virtual laboratory writes data/measured/ (SYNTHETIC).

    python stages/lab.py [seed=N]

Reads only `seed` from conf/config.yaml (no Hydra composition: that would
open the GA profile, which is not a dependency of the lab).
"""

import shutil
import tempfile
from pathlib import Path

from omegaconf import OmegaConf

from dampertwin.config import repo_root
from dampertwin.lab import generate

from _common import stage


def main(*argv: str) -> None:
    root = repo_root(Path(__file__).parent)
    cfg = OmegaConf.merge(OmegaConf.load(root / "conf" / "config.yaml"), OmegaConf.from_dotlist(list(argv)))
    out = root / "data" / "measured"
    # write into a temporary folder, then swap: a killed stage leaves no half-written data
    tmp = Path(tempfile.mkdtemp(prefix=".measured.", dir=out.parent))
    try:
        generate(root / "conf", tmp, seed=int(cfg.seed))
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)


if __name__ == "__main__":
    stage(main, "lab")
