"""Numba functions with explicit signatures, compiled at first use.

``numba.njit(signature)`` compiles when the decorator runs, i.e. when its
module is imported: with a cold cache, importing the solver, the model's
and the truth's right-hand sides took over a minute (a new user's test
collection alone took minutes). :func:`lazy_njit` takes the same arguments
but compiles at the first call, or when another compiled function that
names it (a global) or receives it (an argument) is compiled. It then runs
exactly ``njit(signature, **flags)(func)``: the same signatures, flags and
machine code (the integrator stays compiled once for the first-class
function type of the right-hand sides, not per right-hand side).
"""

from __future__ import annotations

import functools

from numba import njit


class LazyDispatcher:
    """A function compiled as ``njit(sigs, **flags)(py_func)`` on first use;
    :attr:`dispatcher` is that numba dispatcher (the Python function itself
    when NUMBA_DISABLE_JIT is set)."""

    def __init__(self, py_func, sigs, flags):
        functools.update_wrapper(self, py_func)
        self.py_func = py_func
        self._sigs = sigs
        self._flags = flags
        self._dispatcher = None

    @property
    def dispatcher(self):
        """The compiled dispatcher (compiles on the first access). No lock of
        its own (it could deadlock against numba's compiler lock): two threads
        that first use it at once each build one, both valid, one is kept."""
        if self._dispatcher is None:
            self._dispatcher = njit(self._sigs, **self._flags)(self.py_func)
        return self._dispatcher

    @property
    def compiled(self) -> bool:
        """Whether the dispatcher has been built (for tests)."""
        return self._dispatcher is not None

    @property
    def _numba_type_(self):
        """Numba's type of this object (numba.typeof reads this attribute):
        that of the dispatcher, so compiled code that names this function
        types and calls the dispatcher."""
        return self.dispatcher._numba_type_

    def __call__(self, *args):
        """Call the dispatcher; arguments that are themselves lazy (a
        right-hand side given to the integrator) are passed as dispatchers."""
        return self.dispatcher(*(a.dispatcher if isinstance(a, LazyDispatcher) else a for a in args))

    def __reduce__(self):
        return self.__qualname__  # pickled by reference, as the module-level function it replaces

    def __repr__(self):
        return f"<lazy_njit {self.__module__}.{self.__qualname__} ({'compiled' if self.compiled else 'not compiled'})>"


def lazy_njit(sigs, **flags):
    """Decorator: ``numba.njit(sigs, **flags)``, compiled at first use
    instead of at import (module docstring)."""

    def wrap(py_func):
        return LazyDispatcher(py_func, sigs, flags)

    return wrap
