"""Where numba's on-disk cache lives (set before any cached function is
decorated).

Numba's on-disk cache is invalidated only when a function's own file
changes, not when a compiled function it calls (in another file) changes.
So, unless the user chose NUMBA_CACHE_DIR, the cache lives in a folder named
after a hash of every compiled source: the model's submodels, the solver and
the lab's truth. Any edit gives a fresh cache. :func:`configure` runs when
the first of ``dampertwin.model``, ``dampertwin.solver`` (any solver_*
module) or ``dampertwin.truth`` is imported, so a process that imports only
the solver (tests/test_solver.py) or only the truth uses the same folder
and never runs stale machine code.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

_PKG = Path(__file__).resolve().parent


def cache_sources() -> list[Path]:
    """Every source file compiled into the model's right-hand sides and the
    solver (tests/test_model_core.py checks this covers all reachable compiled code)."""
    model = _PKG / "model"
    return sorted(model.glob("*.py")) + [_PKG / "solver.py"] + sorted(_PKG.glob("solver_*.py"))


def cache_dir() -> str:
    """The cache folder of these sources: <XDG cache>/dampertwin/numba/<hash of model, solver and truth>."""
    h = hashlib.sha256()
    for f in cache_sources() + sorted((_PKG / "truth").glob("*.py")):
        h.update(f.read_bytes())
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "dampertwin" / "numba"
    return str(base / h.hexdigest()[:16])


_CONFIGURED = False


def configure() -> None:
    """Point numba's cache at :func:`cache_dir` (once per process) unless the
    user set NUMBA_CACHE_DIR."""
    global _CONFIGURED
    if _CONFIGURED:
        return
    _CONFIGURED = True
    if not os.environ.get("NUMBA_CACHE_DIR"):
        import numba

        numba.config.CACHE_DIR = cache_dir()
