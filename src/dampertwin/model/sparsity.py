"""Jacobian sparsity of an assembled configuration, found by probing its
compiled right-hand side (solver.probe_sparsity) at random states around the
declared rest state, spread over the declared state scales."""

from __future__ import annotations

import numpy as np

from ..solver import Sparsity, probe_sparsity
from .layout import N_OUT, initial_state, state_scales
from .params import EFFECT_INDEX

N_PROBES = 300  # random states per parameter set
PROBE_SPREAD = (-1.0, 2.0)  # log10 of the state perturbation in units of the declared scale
PROBE_SEED = 20240917


def probe_states(p: np.ndarray, cfg: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """n random states: rest state + scale x N(0, 1) x 10^U(PROBE_SPREAD)."""
    y0 = initial_state(p, cfg)
    sc = state_scales(cfg)
    mag = 10.0 ** rng.uniform(*PROBE_SPREAD, size=(n, len(y0)))
    return y0 + sc * mag * rng.standard_normal((n, len(y0)))


def pattern(rhs, cfg: int, P: np.ndarray, ex: np.ndarray, aux: np.ndarray, t_span: tuple[float, float],
            n_probes: int = N_PROBES, seed: int = PROBE_SEED) -> np.ndarray:
    """Union of the probed patterns for the parameter sets P (rows), each
    also with every effect switched on (a superset for any switch setting)."""
    P = np.atleast_2d(np.asarray(P, float))
    rows = [P, P.copy()]
    rows[1][:, list(EFFECT_INDEX.values())] = 1.0
    rng = np.random.default_rng(seed)
    J = None
    for Pk in rows:
        for p in Pk[: max(1, min(len(Pk), 8))]:
            Y = probe_states(p, cfg, n_probes, rng)
            tt = rng.uniform(*t_span, size=n_probes)
            Jp = probe_sparsity(rhs, Y, state_scales(cfg), tt, p[None, :], ex, aux, N_OUT)
            J = Jp if J is None else J | Jp
    return J


def sparsity(rhs, cfg: int, P: np.ndarray, ex: np.ndarray, aux: np.ndarray, t_span: tuple[float, float]) -> Sparsity:
    """Probed pattern and its colouring for the coloured FD Jacobian."""
    return Sparsity.from_pattern(pattern(rhs, cfg, P, ex, aux, t_span))
