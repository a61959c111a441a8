"""Local polish of a GA fit and the uncertainty at its optimum (issue 14).

A GA (thesis 5.1.2) ends near, not at, the optimum. From the best distinct
GA members (multi-start) a bounded trust-region least-squares search
(scipy ``least_squares``, method "trf") continues in gene coordinates.
The thesis' objectives are integrals of absolute errors (eq. 6.1 - 6.3);
least squares minimises them through the smooth "soft_l1" loss
rho(z) = 2 (sqrt(1 + z) - 1) on residuals r_i = w_i e_i (trapezoid weights
w_i [s]), which is quadratic below ``f_scale`` and ~ 2 |r| / f_scale above
it (pseudo-Huber; Triggs et al., "Bundle adjustment - a modern synthesis",
2000, sec. 3.3): with f_scale small against the residuals the search
minimises sum w_i |e_i|, eq. 6.x itself. The polished point is kept only if
it lowers the eq. 6.x objective, so a fit never ends worse than its GA.

The Jacobian is by forward differences with all p + 1 points in one batch
call (parallel simulations), shared with
:mod:`dampertwin.calibration.uncertainty`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import UserError
from .ga import FitResult, ParamSpec
from .problem import Problem, WeightedAbs
from .uncertainty import analyse, central_jacobian, fd_jacobian, other_optima

F_SCALE_FRACTION = 0.1  # soft_l1 f_scale as a fraction of the median |weighted residual| at the start
# The uncertainty's Jacobian is taken from simulations at a tight tolerance (Records.precise):
# at the fits' rtol 1e-4 the forward and backward quotients of the top-mount fit differ by
# 0.53 of the largest singular value (lab 2 sample 1, gene step 1e-3), so every weak
# direction was solver noise and the intervals came out 10-100x too narrow. At rtol 1e-7
# the solver part of the error is still ~0.004 of it at step 3e-3, at 1e-8 below the
# curvature part (docs/validation/approach1.md "What the intervals do not cover").
UNCERTAINTY_RTOL = 1e-8
UNCERTAINTY_ATOL = 1e-6
UNCERTAINTY_STEP = 3e-3  # gene-space step of the uncertainty's central differences


@dataclass(frozen=True)
class PolishSettings:
    """Budget of the local polish: number of start points (best distinct
    GA members at least ``min_distance`` apart in gene space), residual
    evaluations per start (``max_nfev``; each Jacobian costs p + 1 more, in
    one batch) and the finite-difference step in gene space."""

    starts: int = 3
    max_nfev: int = 20
    step: float = 1e-3
    min_distance: float = 0.05

    @classmethod
    def from_config(cls, c, fit: str | None = None) -> "PolishSettings":
        """From a profile's ``polish`` mapping; a sub-mapping named ``fit``
        (e.g. ``valves``) overrides its keys for that fit's polish. A key
        that is neither a setting nor a fit's name (a mistyped ``valve:``)
        raises UserError naming it."""
        for k, v in c.items():
            ok = POLISH_FITS if hasattr(v, "items") else POLISH_KEYS
            if k not in ok or (hasattr(v, "items") and any(kk not in POLISH_KEYS for kk in v)):
                raise UserError(f"profile polish: unknown key {k!r} (settings: {', '.join(POLISH_KEYS)}; a fit's "
                                f"own budget under one of {', '.join(POLISH_FITS)} with the same settings)")
        if fit is not None and fit in c:
            c = {**{k: v for k, v in c.items() if not hasattr(v, "items")}, **c[fit]}
        return cls(int(c["starts"]), int(c["max_nfev"]), float(c.get("step", 1e-3)),
                   float(c.get("min_distance", 0.05)))


POLISH_KEYS = ("starts", "max_nfev", "step", "min_distance")
POLISH_FITS = ("valves", "compliance", "topmount")  # the profile's ga groups of approach 1


class Records(Problem):
    """A fit's measured records against batched simulations: residuals
    e = measured - simulated, concatenated over records, and the eq. 6.x
    objective sum_i w_i |e_i| (trapezoid weights w_i [s], the
    :class:`~.problem.WeightedAbs` cost)."""

    def __init__(self, residuals: Callable, weights: np.ndarray, blocks: list[int] | None = None,
                 precise: Callable | None = None):
        # (m, k) parameter values -> (m, n) residuals with NaN rows for failures,
        # or (residuals, reason per row) to say why a row failed; ``blocks``: the
        # records' lengths in that order (the uncertainty's batches do not span two);
        # ``precise``: the same residuals from simulations at UNCERTAINTY_RTOL (for
        # the uncertainty's Jacobian; None: ``residuals`` are exact, e.g. analytic)
        self._residuals = residuals
        self._precise = precise
        self.cost = WeightedAbs(weights)
        self.blocks = None if blocks is None else [int(b) for b in blocks]

    @property
    def weights(self) -> np.ndarray:
        return self.cost.weights

    def evaluate(self, X: np.ndarray) -> tuple[np.ndarray, list]:
        out = self._residuals(np.atleast_2d(X))
        R, why = out if isinstance(out, tuple) else (out, [None] * len(out))
        return np.asarray(R, float), list(why)

    def precise_residuals(self, X: np.ndarray) -> np.ndarray:
        """Residuals from simulations at the uncertainty's tight tolerance."""
        if self._precise is None:
            return self.residuals(X)
        out = self._precise(np.atleast_2d(X))
        return np.asarray(out[0] if isinstance(out, tuple) else out, float)


def values(specs: list[ParamSpec], G: np.ndarray) -> np.ndarray:
    """Gene rows -> parameter values (unclipped, so intervals may extend past the bounds)."""
    G = np.atleast_2d(G)
    cols = []
    for j, s in enumerate(specs):
        g = G[:, j]
        cols.append(s.lo * (s.hi / s.lo) ** g if s.scale == "log" else s.lo + (s.hi - s.lo) * g)
    return np.column_stack(cols)


def _starts(top: list[np.ndarray], n: int, min_distance: float) -> list[np.ndarray]:
    picked: list[np.ndarray] = []
    for g in top:
        if all(np.linalg.norm(g - p) >= min_distance for p in picked):
            picked.append(g)
        if len(picked) == n:
            break
    return picked


def polish(records: Records, specs: list[ParamSpec], res: FitResult, settings: PolishSettings,
           label: str = "polish", progress: bool = True, nominal: dict | None = None) -> FitResult:
    """Least-squares polish of ``res`` from its best distinct members and,
    with ``nominal`` (key -> value, e.g. the drawings), from there too; the
    result's ``best`` / ``best_objective`` are replaced only by a point with
    a lower eq. 6.x objective. ``res.polish`` reports every start. Every
    other end point inside the best's joint 95 % confidence region widens
    the uncertainty report (:func:`uncertainty.other_optima`)."""
    from scipy.optimize import least_squares
    from ..progress import progress as tqdm

    w = records.weights

    def weighted(G):
        R = np.asarray(records.residuals(values(specs, G)), float) * w
        return R

    starts = _starts(res.top, settings.starts, settings.min_distance)
    if nominal is not None:
        g_nom = np.array([s.to_gene(nominal[s.key]) for s in specs])
        if all(np.linalg.norm(g_nom - g) >= settings.min_distance for g in starts):
            starts.append(g_nom)
    ends = []
    report = {"method": "scipy least_squares trf, soft_l1 loss, bounded in gene space", "starts": []}
    best_g = np.array([s.to_gene(res.best[s.key]) for s in specs])
    best_j = res.best_objective
    for g0 in tqdm(starts, desc=label, disable=not progress, leave=False):
        r0 = weighted(g0[None, :])[0]
        if not np.all(np.isfinite(r0)):
            continue
        big = 10 * np.abs(r0).max()

        def fun(u, big=big):
            r = weighted(u[None, :])[0]
            return np.where(np.isfinite(r), r, big)

        def jac(u):
            _, J = fd_jacobian(lambda G: np.nan_to_num(weighted(G), nan=big), u, settings.step,
                               np.zeros_like(u), np.ones_like(u))
            return J

        f_scale = max(F_SCALE_FRACTION * float(np.median(np.abs(r0))), 1e-300)
        sol = least_squares(fun, np.clip(g0, 0, 1), jac=jac, bounds=(0.0, 1.0), method="trf", loss="soft_l1",
                            f_scale=f_scale, max_nfev=settings.max_nfev, x_scale=1.0)
        j = float(records.objective(values(specs, sol.x[None, :]))[0])
        j0 = float(records.objective(values(specs, g0[None, :]))[0])
        report["starts"].append({"objective_start": j0, "objective_end": j, "nfev": int(sol.nfev),
                                 "njev": int(sol.njev or 0), "status": int(sol.status)})
        res.evaluations += int(sol.nfev) + int(sol.njev or 0) * (len(specs) + 1) + 2
        if np.isfinite(j):
            ends.append((np.clip(sol.x, 0, 1), j))
        if np.isfinite(j) and j < best_j:
            best_j, best_g = j, np.clip(sol.x, 0, 1)
    report["objective_ga"] = res.objective_ga
    report["objective_polished"] = best_j
    res.polish = report
    res.best = {s.key: float(v) for s, v in zip(specs, values(specs, best_g[None, :])[0])}
    res.best_objective = best_j
    res.uncertainty = uncertainty_at(records, specs, best_g)
    if "error" not in res.uncertainty and ends:
        G = np.array([g for g, _ in ends])
        R = np.asarray(records.precise_residuals(values(specs, G)), float)
        alt = [(dict(zip([s.key for s in specs], v)), float(r @ r), j)
               for v, r, (_, j) in zip(values(specs, G), R, ends) if np.all(np.isfinite(r))]
        res.uncertainty = other_optima(res.uncertainty, alt)
    return res


def uncertainty_at(records: Records, specs: list[ParamSpec], g: np.ndarray, step: float = UNCERTAINTY_STEP) -> dict:
    """calibration.uncertainty of the fit at gene point ``g``: residual
    Jacobian by central differences from the precise simulations (one
    batch of 4p + 1), with its error estimate; intervals mapped to values."""
    e0, J, E = central_jacobian(lambda G: records.precise_residuals(values(specs, G)), g, step,
                                np.zeros_like(g), np.ones_like(g))
    if not (np.all(np.isfinite(J)) and np.all(np.isfinite(e0))):
        return {"error": "a simulation failed at or next to the optimum: no Jacobian"}
    u = analyse(J, e0, [s.key for s in specs], g, to_value=lambda j, x: values([specs[j]], np.atleast_1d(x)[:, None])[0, 0],
                blocks=getattr(records, "blocks", None), jac_error=E)
    return {**u.to_dict(), "markdown": u.to_markdown("Identifiability and uncertainty")}
