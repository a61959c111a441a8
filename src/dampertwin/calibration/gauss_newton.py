"""Bounded Levenberg-Marquardt with Broyden Jacobian updates: the
discrepancy workflow's calibration refit, candidate refits and
recalibrations (issue 11), behind :func:`.optimisers.run` with
:class:`GaussNewtonSettings`.

The search runs in the specs' normalised coordinates u in [0, 1]
(:class:`~.ga.ParamSpec`) on the whitened residuals z of a problem whose
cost is :class:`~.problem.WhitenedChi2` (a mask of fitted features). Each
step solves the bounded linear least-squares problem (scipy ``lsq_linear``)

    min || [J_mask; diag(1/sigma); sqrt(lambda) I] du + [z_mask; (u - u_p)/sigma; 0] ||^2

(Levenberg 1944, Marquardt 1963: damping lambda divided by 3 after an
accepted step, multiplied by 10 after a rejected one), the rows diag(1 /
sigma) being the specs' priors (value, sigma in u: Tikhonov rows, so a
refit of many parameters on few records does not trade miscalibration for
overfitting). The Jacobian's columns come from a given ``jacobian`` (key
-> dz/du, e.g. the workflow's sensitivity batch) or one batch of forward
differences at the start; after every step they are updated along it
(Broyden 1965, "good" update), so an iteration costs one evaluation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .ga import FitResult, ParamSpec
from .problem import split_evaluation


@dataclass(frozen=True)
class GaussNewtonSettings:
    """``iterations``: Levenberg-Marquardt steps at most; ``step``:
    forward-difference step in u (taken the other way at the upper bound or
    when the stepped point is invalid); ``tol``: the search ends when no
    coordinate moves more than this [u]; ``damping``: the start lambda."""

    iterations: int
    step: float
    tol: float = 1e-4
    damping: float = 1e-2


def _values(specs: list[ParamSpec], u: np.ndarray) -> list:
    return [p.to_v(x) for p, x in zip(specs, u)]


def _evaluate(problem, specs, anchor, pts: list, counters: dict) -> tuple[list, list]:
    """Whitened residual rows and outputs of the points ``pts`` (u rows) in
    one batch; an invalid point is simulated as ``anchor`` (a valid point)
    and returned as a NaN row."""
    if not pts:
        return [], []
    X, ok = [], []
    for u in pts:
        x = _values(specs, u)
        bad = problem.invalid(x) is not None
        X.append(anchor if bad else x)
        ok.append(not bad)
    Z, _, outs = split_evaluation(problem.evaluate(np.array(X, float)), len(X))
    outs = outs or [None] * len(X)
    counters["evaluations"] += len(X)
    rows = [z if o else np.full_like(z, np.nan) for z, o in zip(Z, ok)]
    outs = [s if o else problem.failed_output(s) for s, o in zip(outs, ok)]
    counters["failed"] += sum(not np.all(np.isfinite(z)) for z in rows)
    return rows, outs


def _start(problem, specs, settings, start, jacobian, counters):
    """u at the specs' starts (pulled inside [0.05, 0.95] when that point is
    invalid), its residual / output and the Jacobian (given columns and a
    forward-difference batch for the rest)."""
    u = np.array([p.to_u(p.start) for p in specs])
    if problem.invalid(_values(specs, u)) is not None:
        u = np.clip(u, 0.05, 0.95)
    anchor = _values(specs, u)
    jacobian = jacobian or {}
    fd = [i for i, p in enumerate(specs) if p.key not in jacobian]
    pts, hs = ([u] if start is None else []), []
    for i in fd:
        v = u.copy()
        h = settings.step if u[i] + settings.step <= 1.0 else -settings.step
        v[i] = u[i] + h
        if problem.invalid(_values(specs, v)) is not None:  # outside the valid set (F_c > F_s, say): the other way
            h = -h
            v[i] = u[i] + h
        hs.append(h)
        pts.append(v)
    rows, outs = _evaluate(problem, specs, anchor, pts, counters)
    z_cur, S_cur = (rows.pop(0), outs.pop(0)) if start is None else start
    J = np.zeros((len(z_cur), len(specs)))
    for i, p in enumerate(specs):
        if p.key in jacobian:
            J[:, i] = jacobian[p.key]
    for k, i in enumerate(fd):
        col = (rows[k] - z_cur) / hs[k]
        J[:, i] = np.where(np.isfinite(col), col, 0.0)
    return u, anchor, z_cur, S_cur, J


def gauss_newton(problem, specs: list[ParamSpec], settings: GaussNewtonSettings, *, start=None,
                 jacobian: dict | None = None) -> FitResult:
    """Minimise the problem's whitened chi^2 (``problem.cost``, a
    :class:`~.problem.WhitenedChi2`) plus the specs' priors over ``specs``
    from their ``start`` values. ``start``: (z, output) already known at the
    start point (no evaluation for it); ``jacobian``: key -> dz/du columns
    already known. The result carries the output at the fit
    (``simulated``), the Broyden-updated Jacobian (``jacobian``, key ->
    dz/du) and the objective per iteration (``history``)."""
    from scipy.optimize import lsq_linear

    counters = {"evaluations": 0, "failed": 0}
    mask, cost = problem.cost.mask, problem.cost
    u, anchor, z_cur, S_cur, J = _start(problem, specs, settings, start, jacobian, counters)
    pc = np.array([p.to_u(p.prior[0]) if p.prior is not None else 0.0 for p in specs])
    pw = np.array([1.0 / p.prior[1] if p.prior is not None else 0.0 for p in specs])
    best = (cost.penalised(z_cur, u, pc, pw), u.copy(), S_cur, z_cur)
    start_objective = best[0]
    lam = settings.damping
    rows = [{"iteration": 0, "objective": best[0], "lambda": lam, "accepted": True}]
    for it in range(settings.iterations):
        if not specs or not np.isfinite(best[0]):
            break
        u, S_cur, z_cur = best[1].copy(), best[2], best[3]
        A = np.vstack([J[mask], np.diag(pw), math.sqrt(lam) * np.eye(len(specs))])
        bb = np.concatenate([-z_cur[mask], -pw * (u - pc), np.zeros(len(specs))])
        du = lsq_linear(A, bb, bounds=(-u - 1e-12, 1.0 - u + 1e-12)).x
        if np.max(np.abs(du)) < settings.tol:
            break
        u_new = np.clip(u + du, 0.0, 1.0)
        du = u_new - u
        (z_new,), (S_new,) = _evaluate(problem, specs, anchor, [u_new], counters)
        if np.all(np.isfinite(z_new)):  # Broyden update of the Jacobian along the step
            J += np.outer(z_new - z_cur - J @ du, du) / float(du @ du)
        c_new = cost.penalised(z_new, u_new, pc, pw)
        accepted = c_new < best[0]
        if accepted:
            best = (c_new, u_new, S_new, z_new)
            lam = max(lam / 3, 1e-4)
        else:
            lam *= 10
        rows.append({"iteration": it + 1, "objective": c_new, "lambda": lam, "accepted": bool(accepted)})
    c, u, S_best, _ = best
    res = FitResult({p.key: p.to_v(x) for p, x in zip(specs, u)}, c, start_objective, pd.DataFrame(rows),
                    counters["failed"], counters["evaluations"], top=[u.copy()])
    res.simulated = S_best
    res.jacobian = {p.key: J[:, i] for i, p in enumerate(specs)}
    return res


__all__ = ["GaussNewtonSettings", "gauss_newton"]
