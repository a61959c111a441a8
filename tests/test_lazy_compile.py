"""Importing the package and collecting the tests compiles nothing (issue 39):
the functions with explicit numba signatures compile at first use
(``dampertwin.jit``), with the same signatures and flags."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

import dampertwin
from conftest import ROOT

# In a fresh interpreter: record every numba compilation (numba's event API)
# while importing every module of the package and every test module.
_IMPORT_ALL = r"""
import importlib, json, pkgutil, sys
from pathlib import Path
from numba.core import event

with event.install_recorder("numba:compile") as rec:
    import dampertwin
    names = [m.name for m in pkgutil.walk_packages(dampertwin.__path__, "dampertwin.")
             if not m.name.endswith("__main__")]
    names += sorted(f.stem for f in Path(sys.argv[1]).glob("*.py") if f.stem != "conftest")
    for name in names:
        importlib.import_module(name)
compiled = [e.data["dispatcher"].py_func.__qualname__ for _, e in rec.buffer if e.is_start]
print(json.dumps({"modules": len(names), "compiled": compiled}))
"""


def test_importing_the_package_and_the_tests_compiles_nothing(tmp_path):
    """With an empty numba cache every compilation is a real one (minutes
    in all); none may run at import."""
    src = Path(dampertwin.__file__).resolve().parents[1]
    tests = ROOT / "tests"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path),
               PYTHONPATH=os.pathsep.join([str(src), str(tests), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", _IMPORT_ALL, str(tests)], env=env, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    rec = json.loads(r.stdout.strip().splitlines()[-1])
    assert rec["modules"] > 50  # the walk really imported the package and the tests
    assert rec["compiled"] == [], f"compiled at import: {rec['compiled']}"


def test_a_lazy_function_compiles_at_first_use_as_njit_would():
    """First use builds njit(signature, **flags): one signature, no further
    specialisation, callable from compiled code and as a first-class
    function argument (no compilation at import is tested above)."""
    from numba import njit, types

    from dampertwin.jit import LazyDispatcher, lazy_njit

    def twice(x):
        return 2.0 * x

    lazy = lazy_njit(types.float64(types.float64), error_model="numpy")(twice)
    assert isinstance(lazy, LazyDispatcher) and not lazy.compiled and lazy.__doc__ == twice.__doc__

    @njit
    def caller(x):  # names the lazy function as a global
        return lazy(x) + 1.0

    assert caller(1.5) == 4.0 and lazy.compiled
    assert [str(s) for s in lazy.dispatcher.signatures] == ["(float64,)"]
    assert lazy.dispatcher.targetoptions["error_model"] == "numpy"
    assert not lazy.dispatcher._can_compile  # like njit(signature): no specialisation for other types
    assert lazy(np.float64(3.0)) == 6.0

    def apply(f, x):
        return f(x)

    fn = types.FunctionType(types.float64(types.float64))  # as the integrator takes a right-hand side
    lazy_apply = lazy_njit(types.float64(fn, types.float64))(apply)
    assert lazy_apply(lazy, 0.25) == 0.5
