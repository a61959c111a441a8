"""Jacobian sparsity of the assembled model and a column colouring, so the
compiled finite-difference Jacobian needs one RHS evaluation per colour
instead of one per state (Curtis-Powell-Reid)."""

from __future__ import annotations

import numpy as np

from . import layout as L


def pattern(cfg: int) -> np.ndarray:
    """Boolean matrix J[i, j]: may d(dy_i)/d(y_j) be non-zero (a superset)."""
    n = L.N_STATES[cfg]
    if cfg in (L.CFG_VALVE, L.CFG_SOLVER_TEST, L.CFG_TOPMOUNT):
        return np.ones((n, n), bool)
    J = np.zeros((n, n), bool)
    PR, PC, PB, VG = L.S_PR, L.S_PC, L.S_PB, L.S_VG
    x = [L.S_X0 + 2 * k for k in range(4)]
    v = [L.S_X0 + 2 * k + 1 for k in range(4)]
    dahl = {0: L.S_DAHL_PR, 2: L.S_DAHL_BC}
    chambers = {0: (PR, PC), 1: (PC, PR), 2: (PC, VG), 3: (VG, PC)}  # valve k: upstream, downstream
    module = cfg == L.CFG_MODULE
    rod = [L.S_XROD, L.S_VROD] if module else []

    def dep(row, *cols):
        for c in cols:
            J[row, c] = True

    dep(PR, PR, PC, PB, x[0], x[1], *rod)  # eq. 4.10
    dep(PC, PR, PC, VG, *x, *rod)  # eq. 4.11 (+ wall vs reserve)
    dep(PB, PR, PB, VG)  # eq. 4.12
    dep(VG, PC, PB, VG, x[2], x[3])  # reserve gas
    for k in range(4):
        dep(x[k], v[k])
        dep(v[k], x[k], v[k], *chambers[k])  # eq. 4.20
        if k in dahl:
            dep(v[k], dahl[k])
            dep(dahl[k], v[k], dahl[k])  # eq. 4.26
    dep(L.S_Z, L.S_Z, *rod)  # eq. 4.40
    if module:
        tm = [L.S_TMX, L.S_TMY, L.S_TMW]
        dep(L.S_XROD, L.S_VROD)
        dep(L.S_VROD, PR, PC, L.S_Z, L.S_XROD, L.S_VROD, *tm)  # eq. 4.4
        dep(L.S_TMX, L.S_VROD, L.S_TMX)  # eq. 4.32
        dep(L.S_TMY, L.S_VROD, L.S_TMX, L.S_TMY)  # eq. 4.33
        dep(L.S_TMW, L.S_VROD, L.S_TMX, L.S_TMW)  # eq. 4.34
    return J


def colouring(J: np.ndarray):
    """Greedy column colouring: columns of one colour share no row.
    Returns (colour per column [n], number of colours, CSC col_ptr, row_idx)."""
    n = J.shape[1]
    colour = -np.ones(n, np.int64)
    order = np.argsort(-J.sum(axis=0), kind="stable")
    for j in order:
        used = {colour[k] for k in range(n) if colour[k] >= 0 and np.any(J[:, k] & J[:, j])}
        c = 0
        while c in used:
            c += 1
        colour[j] = c
    col_ptr = np.zeros(n + 1, np.int64)
    rows = []
    for j in range(n):
        r = np.flatnonzero(J[:, j])
        rows.extend(r)
        col_ptr[j + 1] = col_ptr[j] + len(r)
    return colour, int(colour.max()) + 1, col_ptr, np.asarray(rows, np.int64)
