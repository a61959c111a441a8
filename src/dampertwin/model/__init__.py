"""Physics submodels of the semi-active damper (thesis chapter 4).

Numba's on-disk cache is invalidated only when a function's own file
changes, not when a compiled function it calls (in another module) changes.
So, unless the user chose NUMBA_CACHE_DIR, the cache lives in a folder named
after a hash of all compiled sources: any edit gives a fresh cache. The lab's
truth (dampertwin.truth) compiles into the same folder once this package is
imported in a process, so its sources are hashed too (else an edit of a truth
function called from another truth file ran stale machine code there).
"""

import hashlib
import os
from pathlib import Path


def cache_sources() -> list[Path]:
    """Every source file compiled into the right-hand sides and the solver
    (tests/test_model_core.py checks this covers all reachable compiled code)."""
    pkg = Path(__file__).resolve().parent
    return sorted(pkg.glob("*.py")) + [pkg.parent / "solver.py"] + sorted(pkg.parent.glob("solver_*.py"))


def _cache_dir() -> str:
    h = hashlib.sha256()
    truth = sorted((Path(__file__).resolve().parent.parent / "truth").glob("*.py"))
    for f in cache_sources() + truth:
        h.update(f.read_bytes())
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "dampertwin" / "numba"
    return str(base / h.hexdigest()[:16])


if not os.environ.get("NUMBA_CACHE_DIR"):
    import numba

    numba.config.CACHE_DIR = _cache_dir()

# Load the submodels in layout's declared order: a direct first import of one of
# them (e.g. `import dampertwin.model.params`, as the docs hook does) would
# otherwise meet the chambers -> layout -> bench cycle half-initialised.
from . import layout as _layout  # noqa: E402,F401
