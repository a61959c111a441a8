"""One entry to the calibration core's optimisers (issue 33):
``run(problem, specs, settings) -> FitResult``.

- ``GASettings``: the pygad GA (:func:`~.ga.run_ga`, thesis 5.1.2) on the
  problem's batch objective, then, with ``polish``, the least-squares polish
  from its best members (:func:`~.polish.polish`: the study's approach 1);
- ``LeastSquaresSettings``: bounded least squares on the problem's
  residuals from Latin-hypercube starts in the unit box of the specs (the
  friction fit).

A *problem* is a :class:`~.polish.Records` (``residuals(X)`` of parameter
rows, ``scores(X)``: eq. 6.x objective and failure reason per row) or, for
the GA alone, a batch objective ``f(X) -> values | (values, reasons)``.
The concurrent GAs of approach 2 (:func:`~.concurrent.run_concurrent`) and
the discrepancy refits' Gauss-Newton keep their own entry points (their
problems score several objectives per simulation / penalised residuals).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..parallel import release
from .ga import Evaluator, FitResult, GASettings, ParamSpec, bound_hits, run_ga
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


def run(problem, specs: list[ParamSpec], settings, *, seed: int = 0, x0: dict | None = None,
        polish_settings: PolishSettings | None = None, checkpoint=None, scheduler: str | None = None,
        label: str = "fit", progress: bool = False, context: str = "", extra=()) -> FitResult:
    """Minimise ``problem`` over ``specs`` with the optimiser ``settings``
    name. ``x0``: the nominal values (a GA member, a polish start);
    ``checkpoint``: a store for the GA's state (:mod:`dampertwin.checkpoint`); ``extra``: further
    unit-box start points of the least squares. The result lists the
    fitted values that end on their search bounds (``bound_hits``)."""
    if isinstance(settings, LeastSquaresSettings):
        return _least_squares(problem, specs, settings, seed, extra)
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


__all__ = ["LeastSquaresSettings", "run"]
