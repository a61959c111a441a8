"""Annular plate bending for shim stacks (setup time, not per step).

A shim is an annular plate clamped at its inner radius b and free at its
outer radius a. Its axisymmetric deflection is the general solution of
D nabla^4 w = q, w = C1 + C2 r^2 + C3 ln r + C4 r^2 ln r + q r^4 / (64 D),
with D = E t^3 / (12 (1 - nu^2)) (Timoshenko & Woinowsky-Krieger, Theory of
Plates and Shells, 2nd ed. 1959, 2.15 and 2.18; Roark's Formulas for Stress
and Strain, 7th ed., table 11.2 cases 1L and 2L tabulate the same
solutions). The pressure acts on r1..a; the region b..r1 is unloaded.
"""

from __future__ import annotations

import math

import numpy as np


def rigidity(E: float, nu: float, t: float) -> float:
    """Flexural rigidity D = E t^3 / (12 (1 - nu^2)) [N m]."""
    return E * t ** 3 / (12.0 * (1.0 - nu * nu))


def _rows(r: float, D: float, nu: float):
    """Rows (w, w', M_r, V) of the homogeneous solution's four terms at r,
    V = D d(nabla^2 w)/dr the shear resultant per unit length."""
    ln = math.log(r)
    w = [1.0, r * r, ln, r * r * ln]
    dw = [0.0, 2 * r, 1.0 / r, 2 * r * ln + r]
    d2w = [0.0, 2.0, -1.0 / (r * r), 2 * ln + 3.0]
    M = [-D * (d2w[k] + nu * dw[k] / r) for k in range(4)]
    V = [0.0, 0.0, 0.0, D * 4.0 / r]
    return np.array([w, dw, M, V])


def _particular(r: float, D: float, nu: float, q: float):
    """(w, w', M_r, V) of the particular solution q r^4 / (64 D)."""
    w = q * r ** 4 / (64 * D)
    dw = q * r ** 3 / (16 * D)
    d2w = 3 * q * r * r / (16 * D)
    return np.array([w, dw, -D * (d2w + nu * dw / r), q * r / 2.0])


def edge_deflection(a: float, b: float, t: float, E: float, nu: float, q: float = 0.0, r1: float | None = None,
                    W: float = 0.0, at: float | None = None) -> float:
    """Deflection [m] at radius ``at`` (default a) of an annular plate
    clamped at b, free at a, under a pressure q [Pa] on r1..a (default
    b..a) and an upward ring load W [N] at its edge a."""
    D = rigidity(E, nu, t)
    r1 = b if r1 is None else r1
    at = a if at is None else at
    n2 = r1 > b * (1 + 1e-9)  # two regions: b..r1 unloaded, r1..a loaded
    nu_k = 8 if n2 else 4
    A = np.zeros((nu_k, nu_k))
    rhs = np.zeros(nu_k)
    o2 = 4 if n2 else 0  # columns of the loaded region
    rb = _rows(b, D, nu)
    A[0, :4], A[1, :4] = rb[0], rb[1]
    pb = _particular(b, D, nu, q) if not n2 else np.zeros(4)
    rhs[0], rhs[1] = -pb[0], -pb[1]
    ra = _rows(a, D, nu)
    pa = _particular(a, D, nu, q)
    # free edge: M_r = 0 and V(a) = -W / (2 pi a) (2 pi r V = load inside r, the clamp reaction included)
    A[2, o2:o2 + 4], rhs[2] = ra[2], -pa[2]
    A[3, o2:o2 + 4], rhs[3] = ra[3], -W / (2 * math.pi * a) - pa[3]
    if n2:  # continuity of w, w', M_r, V at r1 (the particular solution lives in r1..a)
        r = _rows(r1, D, nu)
        pr = _particular(r1, D, nu, q)
        for k in range(4):
            A[4 + k, :4] = r[k]
            A[4 + k, 4:] = -r[k]
            rhs[4 + k] = pr[k]
    c = np.linalg.solve(A, rhs)
    loaded = not n2 or at >= r1
    w = _rows(at, D, nu)[0] @ (c[o2:o2 + 4] if loaded else c[:4])
    if loaded:
        w += _particular(at, D, nu, q)[0]
    return float(w)


def stack(a: float, b: float, t: float, n: int, E: float, nu: float, r1: float) -> dict:
    """A stack of n equal shims bending together without friction (rigidities
    add): stiffness at the edge k = W / w(a) [N/m] and the pressure-equivalent
    area A = k w(a)/q [m^2] (by Maxwell-Betti also the volume swept per unit
    edge lift on the loaded side)."""
    k = 1.0 / edge_deflection(a, b, t, E, nu, W=1.0) * n
    area = edge_deflection(a, b, t, E, nu, q=1.0, r1=r1) * k / n
    return {"k": k, "area": area}


def shape_ratio(a: float, b: float, r: float, t: float, E: float, nu: float) -> float:
    """w(r) / w(a) of the plate under its edge ring load."""
    return edge_deflection(a, b, t, E, nu, W=1.0, at=r) / edge_deflection(a, b, t, E, nu, W=1.0)
