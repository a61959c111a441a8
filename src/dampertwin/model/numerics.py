"""Elementary functions the right-hand side calls many times per step.

``x ** a`` with a parameter exponent compiles to a libm ``pow`` call
(~100 CPU cycles); the exponents the designs use most (1, 2, 1/2) are exact
cheap operations. Measured in bench/README.md ("RHS cost")."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, error_model="numpy")
def power(x, a):
    """x ** a for x >= 0, with a = 1, 2 and 1/2 as x, x*x and sqrt(x)
    (correctly rounded, so equal to pow's result to the last bit or one ulp)."""
    if a == 1.0:
        return x
    if a == 2.0:
        return x * x
    if a == 0.5:
        return math.sqrt(x)
    return x ** a
