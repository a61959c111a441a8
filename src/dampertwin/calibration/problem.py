"""Problem and Cost of the calibration core (issue 33).

A :class:`Problem` is a design, measured records and the channels compared:
``evaluate(X)`` maps a batch of parameter rows (values [SI], columns in the
fit's spec order) to residual rows (measured - simulated, NaN rows for
failed members) and a failure reason per row (None where the member ran);
it may add the simulated output per row (a third item; the Gauss-Newton
refits keep the features at the fit). A :class:`Cost` turns residual rows
into the objective(s) an optimiser minimises:

- :class:`WeightedAbs`: eq. 6.1 - 6.3 / 7.1 unweighted, sum_i w_i |e_i|
  with trapezoid weights w_i [s] (approach 1, approach 2's best-solution
  tracker);
- :class:`RecordsAbs`: the same, record by record on each record's own
  time base (``dampertwin fit``'s submodel fits);
- :class:`GroupedAbs`: approach 2's concurrent GAs, eq. 7.1
  J_g = sum_i w_i I_g(t_i) |e_i| per valve group (sensitivity weights I_g),
  unweighted for the other groups, then the unweighted integral;
- :class:`WhitenedChi2`: the discrepancy refits' sum of squared whitened
  residuals over a mask of features, plus the priors of the specs
  (Tikhonov rows, :mod:`.gauss_newton`).

``scores(X)`` (objective per row, reason per failed row) is what the GAs
evaluate; ``residuals(X)`` what the least-squares searches see. The
optimisers (:func:`.optimisers.run`) know nothing else of a problem.
"""

from __future__ import annotations

import math

import numpy as np

from .sensitivity import row_integrals, weighted_integrals


def split_evaluation(out, m: int | None = None) -> tuple[np.ndarray, list, list | None]:
    """A problem's ``evaluate`` return -> (residual rows, reasons, outputs or
    None): residuals alone, (residuals, reasons) or (residuals, reasons,
    outputs)."""
    if isinstance(out, tuple):
        R, why = np.asarray(out[0], float), list(out[1])
        extra = list(out[2]) if len(out) > 2 else None
    else:
        R, why, extra = np.asarray(out, float), [None] * len(out), None
    if m is not None and (len(R) != m or len(why) != m):
        raise ValueError(f"problem returned {len(R)} residual rows / {len(why)} reasons for {m} members")
    return R, why, extra


class Cost:
    """Residual rows (m, n) -> objective per row (m,) or per row and
    objective (m, k). NaN where a row is not finite."""

    def __call__(self, R: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class WeightedAbs(Cost):
    """Eq. 6.1 - 6.3: sum_i w_i |e_i| (trapezoid weights ``w`` [s]), row by
    row so a row's value has the same bits in any batch."""

    def __init__(self, weights: np.ndarray):
        self.weights = np.asarray(weights, float)

    def __call__(self, R: np.ndarray) -> np.ndarray:
        return row_integrals(np.abs(R), self.weights)


class RecordsAbs(Cost):
    """Eq. 6.1 - 6.3 summed over records with their own time bases: for
    each record (times ``t``, its block of the residual row, in order)
    int |e| dt by the trapezoid rule, NaN for a row whose record is not
    finite (``dampertwin fit``'s submodel fits)."""

    def __init__(self, times: list[np.ndarray]):
        self.times = [np.asarray(t, float) for t in times]

    def __call__(self, R: np.ndarray) -> np.ndarray:
        R = np.atleast_2d(R)
        J, k = np.zeros(len(R)), 0
        for t in self.times:
            E = np.abs(R[:, k:k + len(t)])
            J += np.array([float(np.trapezoid(e, t)) if np.all(np.isfinite(e)) else float("nan") for e in E])
            k += len(t)
        return J


class GroupedAbs(Cost):
    """Approach 2 (thesis Algorithm 1): eq. 7.1 J_g = int I_g(t) |e| dt for
    the groups with sensitivity weights (rows of ``W``), the unweighted
    integral for the ``n_unweighted`` other groups (compliance, L1511) and,
    last, the unweighted integral (the best-solution tracker). (m, G + 1)."""

    def __init__(self, quad: np.ndarray, W: np.ndarray, n_unweighted: int = 1):
        self.quad, self.W, self.n_unweighted = np.asarray(quad, float), np.asarray(W, float), int(n_unweighted)

    @property
    def n_objectives(self) -> int:
        return len(self.W) + self.n_unweighted + 1

    def __call__(self, R: np.ndarray) -> np.ndarray:
        A = np.abs(R)
        J = weighted_integrals(A, self.quad, self.W)
        total = row_integrals(A, self.quad)  # row by row: the same bits in any batch
        return np.column_stack([J, *([total] * self.n_unweighted), total])


def chi(z: np.ndarray, mask: np.ndarray) -> float:
    """Sum of squared whitened residuals over ``mask`` (inf when a member failed)."""
    v = z[..., mask]
    return float(np.sum(v * v)) if np.all(np.isfinite(v)) else math.inf


class WhitenedChi2(Cost):
    """The discrepancy refits' objective: sum of squared whitened residuals
    z over the features in ``mask`` (inf when a feature is not finite), and,
    with :meth:`penalised`, the specs' priors as (u - u_prior) / sigma_u."""

    def __init__(self, mask: np.ndarray):
        self.mask = np.asarray(mask, bool)

    def __call__(self, R: np.ndarray) -> np.ndarray:
        return np.array([chi(r, self.mask) for r in np.atleast_2d(R)])

    def penalised(self, z: np.ndarray, u: np.ndarray, centre: np.ndarray, weight: np.ndarray) -> float:
        """chi^2 of one row plus the prior term sum (weight (u - centre))^2."""
        return chi(z, self.mask) + float(np.sum((weight * (u - centre)) ** 2))


class Problem:
    """Records + channels -> residuals of parameter rows, a reason for every
    failed member, and the objective(s) of its :class:`Cost`. Subclasses
    implement :meth:`evaluate`; ``cost`` is set by the subclass (or passed)."""

    cost: Cost | None = None

    def evaluate(self, X: np.ndarray):
        """(m, k) parameter values -> (residuals (m, n), reasons[, outputs])."""
        raise NotImplementedError

    def invalid(self, x) -> str | None:
        """Why the parameter row ``x`` lies outside the model's valid set
        (None: it does not); checked before a simulation by the optimisers
        that step to new points (Gauss-Newton)."""
        return None

    def failed_output(self, output):
        """The output recorded for an invalid member (its stand-in's output emptied)."""
        return None

    def residuals(self, X: np.ndarray) -> np.ndarray:
        return split_evaluation(self.evaluate(np.atleast_2d(X)))[0]

    def scores(self, X: np.ndarray) -> tuple[np.ndarray, list]:
        """(objective per row [or per row and objective], reason per failed
        row): the GAs' batch objective. A row with a non-finite residual
        scores NaN and says so."""
        R, why, _ = split_evaluation(self.evaluate(np.atleast_2d(X)))
        J = self.cost(R)
        ok = np.all(np.isfinite(R), axis=1)
        J = np.where(ok if J.ndim == 1 else ok[:, None], J, np.nan)
        return J, [w or (None if o else "non-finite residual") for w, o in zip(why, ok)]

    def objective(self, X: np.ndarray) -> np.ndarray:
        return self.scores(X)[0]


__all__ = ["Problem", "Cost", "WeightedAbs", "RecordsAbs", "GroupedAbs", "WhitenedChi2", "chi", "split_evaluation"]
