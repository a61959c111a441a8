"""The calibration core's one entry (issue 33):
``run(problem, specs, settings) -> FitResult``.

A *problem* (:class:`~.problem.Problem`) maps parameter rows to residual
rows with a failure reason per member and scores them with its
:class:`~.problem.Cost`; *specs* are the one parameter spec
(:class:`~.ga.ParamSpec`: key, bounds, scale, start, prior); the type of
*settings* names the optimiser:

- :class:`~.ga.GASettings`: the pygad GA (:func:`~.ga.run_ga`, thesis
  5.1.2) on ``problem.scores`` (or a bare batch objective ``f(X) -> values
  | (values, reasons)``), then, with ``polish_settings``, the least-squares
  polish from its best members (:func:`~.polish.polish`): approach 1 and
  ``dampertwin fit``;
- :class:`~.concurrent.ConcurrentSettings`: the concurrent,
  sensitivity-weighted GAs of approach 2 (thesis Algorithm 1,
  :func:`~.concurrent.run_concurrent`); ``specs`` is then the list of
  :class:`~.concurrent.GAGroup` (one GA each) and ``problem.scores`` gives
  one objective per group plus the unweighted one
  (:class:`~.problem.GroupedAbs`);
- :class:`LeastSquaresSettings`: bounded least squares on
  ``problem.residuals`` from Latin-hypercube starts in the unit box of the
  specs (the friction fit);
- :class:`~.gauss_newton.GaussNewtonSettings`: bounded Levenberg-Marquardt
  with Broyden updates on a whitened chi^2 with the specs' priors
  (:class:`~.problem.WhitenedChi2`): the discrepancy workflow's calibration
  refit, candidate refits and recalibrations.

Every optimiser returns the core's :class:`~.ga.FitResult` (values,
objective history, failures, bound hits, and what that optimiser adds).
GA checkpoints go to a store passed in (:mod:`dampertwin.checkpoint`): no
file I/O in the optimisers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..parallel import release
from .concurrent import BatchScorer, ConcurrentSettings, run_concurrent
from .ga import Evaluator, FitResult, GASettings, ParamSpec, bound_hits, run_ga
from .gauss_newton import GaussNewtonSettings, gauss_newton
from .polish import PolishSettings, polish


@dataclass(frozen=True)
class LeastSquaresSettings:
    """Multi-start bounded least squares (scipy ``least_squares``, trf):
    Latin-hypercube starts in the unit box, evaluations per start
    ``nfev_per_parameter`` x parameters, relative finite-difference step."""

    starts: int = 8
    nfev_per_parameter: int = 200
    diff_step: float = 1e-4


def _least_squares(problem, specs: list[ParamSpec], settings: LeastSquaresSettings, seed: int,
                   extra=()) -> FitResult:
    from scipy.optimize import least_squares
    from scipy.stats import qmc

    from .polish import values

    n = len(specs)

    def resid(g):
        return np.asarray(problem.residuals(values(specs, g[None, :])), float)[0]

    x0s = list(qmc.LatinHypercube(d=n, seed=np.random.default_rng(seed)).random(max(settings.starts, 1)))
    x0s += list(extra)
    best, rows, evals = None, [], 0
    for i, x0 in enumerate(x0s):
        r = least_squares(resid, np.clip(x0, 0.0, 1.0), bounds=(0.0, 1.0), x_scale=1.0,
                          diff_step=settings.diff_step, max_nfev=settings.nfev_per_parameter * n)
        evals += int(r.nfev) * (n + 1)
        rows.append({"start": i, "objective": float(r.cost), "nfev": int(r.nfev), "status": int(r.status)})
        if best is None or r.cost < best.cost:
            best = r
    res = FitResult({s.key: float(s.to_value(g)) for s, g in zip(specs, best.x)}, float(best.cost), float("nan"),
                    pd.DataFrame(rows), 0, evals, top=[np.asarray(best.x, float)], objective_ga=float("nan"))
    res.specs, res.records = specs, problem
    res.bound_hits = bound_hits(specs, res.best)
    return res


def run(problem, specs: list, settings, *, seed: int = 0, x0: dict | None = None,
        polish_settings: PolishSettings | None = None, checkpoint=None, scheduler: str | None = None,
        label: str = "fit", progress: bool = False, context: str = "", extra=(), start=None,
        jacobian: dict | None = None) -> FitResult:
    """Minimise ``problem`` over ``specs`` with the optimiser ``settings``
    name. ``x0``: the nominal values (a GA member, a polish start);
    ``checkpoint``: a store for the GAs' state (:mod:`dampertwin.checkpoint`);
    ``scheduler``: a Dask address for the GAs' populations; ``extra``:
    further unit-box start points of the least squares; ``start`` /
    ``jacobian``: the Gauss-Newton's known residual and output at the start
    / Jacobian columns. The result lists the fitted values that end on
    their search bounds (``bound_hits``)."""
    if isinstance(settings, LeastSquaresSettings):
        return _least_squares(problem, specs, settings, seed, extra)
    if isinstance(settings, GaussNewtonSettings):
        res = gauss_newton(problem, specs, settings, start=start, jacobian=jacobian)
        res.specs, res.records, res.bound_hits = list(specs), problem, bound_hits(specs, res.best)
        return res
    if isinstance(settings, ConcurrentSettings):
        scorer = BatchScorer(problem.scores, len(specs) + 1, scheduler)
        try:
            res = run_concurrent(specs, scorer, settings.ga, seed, x0=x0, checkpoint=checkpoint, label=label,
                                 progress=progress, context=context)
        finally:
            release(scorer)
        res.specs, res.records = [s for g in specs for s in g.specs], problem
        return res
    if not isinstance(settings, GASettings):
        raise TypeError(f"run: unknown optimiser settings {type(settings).__name__}")
    objective = problem.scores if hasattr(problem, "scores") else problem
    ev = Evaluator(objective, scheduler)
    try:
        res = run_ga(specs, ev, settings, seed, x0=x0, checkpoint=checkpoint, label=label, progress=progress,
                     context=context)
    finally:
        release(ev)
    if polish_settings is not None:
        res = polish(problem, specs, res, polish_settings, label=f"{label} polish", progress=progress, nominal=x0)
    res.specs, res.records = specs, problem if hasattr(problem, "scores") else None
    res.bound_hits = bound_hits(specs, res.best)
    return res


__all__ = ["ConcurrentSettings", "GaussNewtonSettings", "LeastSquaresSettings", "run"]
