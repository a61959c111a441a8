"""Test problems for the integrator, independent of the damper model.

Each is compiled with the solver's RHS signature: rhs(t, y, p, ex, aux, dy, out),
at first use (collecting the tests compiles nothing).
"""

from __future__ import annotations

import math

import numpy as np

from dampertwin.jit import lazy_njit
from dampertwin.solver import rhs_signature

SIG = rhs_signature()


@lazy_njit(SIG, cache=True, error_model="numpy")
def prothero_robinson(t, y, p, ex, aux, dy, out):
    """y0' = -lam (y0 - sin t) + cos t (exact sin t from 0; stiffness lam = p[0]),
    y1' = -y1^2 (exact 1 / (1 + t) from 1): non-autonomous and nonlinear."""
    dy[0] = -p[0] * (y[0] - math.sin(t)) + math.cos(t)
    dy[1] = -y[1] * y[1]
    out[0] = y[0]
    out[1] = y[1]


def prothero_robinson_exact(t):
    return np.column_stack([np.sin(t), 1.0 / (1.0 + t)])


@lazy_njit(SIG, cache=True, error_model="numpy")
def linear(t, y, p, ex, aux, dy, out):
    """y' = A y with A = [[-p0, 1], [0, -p1]] (stiff when p0 >> p1): exact
    y0 = e^{-p0 t}(y0(0) - c) + c e^{-p1 t}, c = y1(0)/(p0 - p1), y1 = y1(0) e^{-p1 t}.
    A negative p makes it blow up (for failure isolation tests)."""
    dy[0] = -p[0] * y[0] + y[1]
    dy[1] = -p[1] * y[1]
    out[0] = y[0]
    out[1] = y[1]


def linear_exact(t, p0, p1, y00, y10):
    c = y10 / (p0 - p1)
    return np.column_stack([np.exp(-p0 * t) * (y00 - c) + c * np.exp(-p1 * t), y10 * np.exp(-p1 * t)])


@lazy_njit(SIG, cache=True, error_model="numpy")
def van_der_pol(t, y, p, ex, aux, dy, out):
    """y0' = y1, y1' = mu (1 - y0^2) y1 - y0, mu = p[0] (stiff for mu >> 1)."""
    dy[0] = y[1]
    dy[1] = p[0] * (1.0 - y[0] * y[0]) * y[1] - y[0]
    out[0] = y[0]
    out[1] = y[1]


def van_der_pol_jacobian(y, mu):
    return np.array([[0.0, 1.0], [-2.0 * mu * y[0] * y[1] - 1.0, mu * (1.0 - y[0] ** 2)]])


@lazy_njit(SIG, cache=True, error_model="numpy")
def robertson(t, y, p, ex, aux, dy, out):
    """Robertson's stiff chemical kinetics (Hairer & Wanner IV.1)."""
    dy[0] = -0.04 * y[0] + 1e4 * y[1] * y[2]
    dy[2] = 3e7 * y[1] * y[1]
    dy[1] = -dy[0] - dy[2]
    out[0] = y[0]
    out[1] = y[1]
    out[2] = y[2]


@lazy_njit(SIG, cache=True, error_model="numpy")
def chain(t, y, p, ex, aux, dy, out):
    """A tridiagonal nonlinear chain (sparse Jacobian for colouring tests):
    y_i' = -y_i^3 + p0 (y_{i-1} - 2 y_i + y_{i+1}) + sin(t) (ends held at 0)."""
    n = y.shape[0]
    for i in range(n):
        left = y[i - 1] if i > 0 else 0.0
        right = y[i + 1] if i < n - 1 else 0.0
        dy[i] = -y[i] ** 3 + p[0] * (left - 2.0 * y[i] + right) + math.sin(t)
    out[0] = y[0]


def chain_jacobian(y, p0):
    n = len(y)
    J = np.zeros((n, n))
    for i in range(n):
        J[i, i] = -3 * y[i] ** 2 - 2 * p0
        if i > 0:
            J[i, i - 1] = p0
        if i < n - 1:
            J[i, i + 1] = p0
    return J
