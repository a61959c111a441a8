"""DVC stage `lab`: the virtual laboratory writes data/measured/ (SYNTHETIC).

    python stages/lab.py [hydra overrides...]
"""

import shutil
import tempfile
from pathlib import Path

from dampertwin.config import compose, repo_root
from dampertwin.lab import generate

from _common import stage


def main(*argv: str) -> None:
    root = repo_root(Path(__file__).parent)
    cfg = compose(list(argv), root)
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
