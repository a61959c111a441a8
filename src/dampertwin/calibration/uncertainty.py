"""Identifiability and uncertainty of a fit at its optimum (issue 14).

Linearised least-squares theory (Bates & Watts, "Nonlinear Regression
Analysis and Its Applications", 1988, ch. 2; Seber & Wild, "Nonlinear
Regression", 1989, sec. 2.1): with residuals r (n samples) and their
Jacobian J = dr/dtheta at the optimum, the Fisher information is
J^T J / s^2 and

    cov(theta) = s^2 (J^T J)^+ * n / n_eff,     s^2 = r.r / (n - p),

where ``n_eff`` is the effective number of independent samples: residuals
of kHz records are strongly autocorrelated, and treating every sample as
independent would shrink the intervals by sqrt(n / n_eff). ``n_eff`` from
the lag-1 autocorrelation of the residuals, the AR(1) approximation
n (1 - rho) / (1 + rho) (Bayley & Hammersley 1946; von Storch & Zwiers,
"Statistical Analysis in Climate Research", 1999, sec. 17.1), unless the
caller knows better (e.g. the number of test cycles). 95 % intervals use
Student's t with n_eff - p degrees of freedom.

The AR(1) factor is one number for all parameters, but a misfit the model
cannot follow (a bench or physics difference) is slow and correlated
where one parameter's sensitivity is and not another's: the intervals
then flatter some parameters many times over. Each interval is therefore
also computed from the batch-means sandwich covariance
A^+ S A^+ (A = J^T J, S the covariance of the score sums J_b^T r_b over
``BATCHES`` contiguous batches; White 1982, Econometrica 50:1-25, for the
misspecified-model sandwich; Ibragimov & Mueller 2010, J. Bus. Econ.
Stat. 28:453-468, for batches and t with B - 1 dof), and the wider of the
two is reported (the sandwich alone is biased low when few batches see
very different inputs, e.g. smooth regressors). Neither covers a bias: a model error the data prefer to
the truth moves the optimum itself (docs/validation/approach1.md, "What the intervals do not
cover").

The Jacobian is by central differences with an estimate of its own error
(:func:`central_jacobian`): a residual from an adaptive ODE solver is not
a smooth function of the parameters (the step sequence changes with them),
and a singular value of J is known only to within the norm of J's error
(Weyl's inequality; Golub & Van Loan, "Matrix Computations", 4th ed.,
cor. 8.6.2). A direction whose singular value is below that error is not
resolved: the intervals of the parameters that load it are unbounded,
however small the pseudo-inverse would make them.

A parameter the data cannot determine is flagged when its interval
half-width exceeds ``rel_ci_max`` of its value, when it correlates with
another beyond ``corr_max``, or when it loads a near-singular direction of
the scaled Fisher matrix (singular value ratio below ``sv_min``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import pandas as pd
from scipy import stats

from ..io import json_number

REL_CI_MAX = 1.0   # CI half-width / |value| above which a parameter is undetermined
CORR_MAX = 0.95    # |correlation| above which a pair is not separately identifiable
SV_MIN = 1e-6      # singular value / largest singular value of the scaled Jacobian: a singular direction
NULL_LOADING = 0.3  # |component| of a parameter in a singular direction that flags it
JAC_NOISE_FACTOR = 1.5  # floor = this x ||E||_2: the extrapolated quotient's noise is 1.2x that of
                        # E = J_h - J_2h (weights 4/3 and -1/3), with a margin for its own scatter
BATCHES = 10       # contiguous batches of the score series for the sandwich covariance (min 2 samples each)


def effective_sample_size(r: np.ndarray) -> float:
    """AR(1) effective sample size n (1 - rho1) / (1 + rho1) of a residual
    series (rho1: lag-1 autocorrelation), between 2 and n."""
    r = np.asarray(r, float) - np.mean(r)
    n = len(r)
    den = float(r @ r)
    if n < 3 or den == 0:
        return float(n)
    rho = float(np.clip((r[:-1] @ r[1:]) / den, -0.99, 0.999999))
    return float(np.clip(n * (1 - rho) / (1 + rho), 2.0, n))


def fd_jacobian(residuals_batch: Callable[[np.ndarray], np.ndarray], x: np.ndarray, step: float | np.ndarray = 1e-3,
                lo: np.ndarray | None = None, hi: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Forward-difference Jacobian of a vector residual at ``x``, all p + 1
    points in one batch call (``residuals_batch``: (m, p) -> (m, n)). A step
    that would leave [lo, hi] is taken backwards. Returns (r(x), J (n, p))."""
    x = np.asarray(x, float)
    p = len(x)
    h = np.broadcast_to(np.asarray(step, float), (p,)).copy()
    if hi is not None:
        h = np.where(x + h > np.asarray(hi), -h, h)
    if lo is not None:
        h = np.where(x + h < np.asarray(lo), np.abs(h), h)
    X = np.vstack([x, x + np.diag(h)])
    R = np.asarray(residuals_batch(X), float)
    return R[0], ((R[1:] - R[0]) / h[:, None]).T


def central_jacobian(residuals_batch: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
                     step: float | np.ndarray = 1e-3, lo: np.ndarray | None = None,
                     hi: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Jacobian of a vector residual at ``x`` from central quotients at steps
    h and 2h, Richardson-extrapolated (4 J_h - J_2h) / 3, all 4p + 1 points in
    one batch call, with an estimate of its error. Returns (r(x), J (n, p),
    E (n, p)), E = J_h - J_2h: for a smooth residual -h^2 r'''/2, several
    times the error of J (a curvature r'' does not enter it), plus the
    residual's own noise (an ODE solver's step sequence changes with the
    parameters) over h. Where x - 2h or x + 2h would leave [lo, hi] the
    column is one-sided of second order from x, x + s h, x + 2 s h (s
    pointing inside), compared with the same from x, x + 2 s h, x + 4 s h."""
    x = np.asarray(x, float)
    p = len(x)
    h = np.broadcast_to(np.asarray(step, float), (p,)).copy()
    lo_ = np.full(p, -np.inf) if lo is None else np.asarray(lo, float)
    hi_ = np.full(p, np.inf) if hi is None else np.asarray(hi, float)
    central = (x + 2 * h <= hi_) & (x - 2 * h >= lo_)
    s = np.where(central | (x + 4 * h <= hi_), 1.0, -1.0)
    offsets = np.where(central[:, None], np.array([1.0, -1.0, 2.0, -2.0])[None, :] * h[:, None],
                       np.array([1.0, 2.0, 3.0, 4.0])[None, :] * (s * h)[:, None])  # (p, 4)
    X = np.vstack([x] + [x + np.diag(offsets[:, k]) for k in range(4)])
    R = np.asarray(residuals_batch(X), float)
    r0 = R[0]
    P = [R[1 + k * p: 1 + (k + 1) * p] for k in range(4)]  # P[k][j]: column j at its k-th offset
    J = np.empty((len(r0), p))
    E = np.empty((len(r0), p))
    for j in range(p):
        a, b, c, d = (P[k][j] for k in range(4))
        if central[j]:
            j1 = (a - b) / (2 * h[j])          # offsets +h, -h
            j2 = (c - d) / (4 * h[j])          # offsets +2h, -2h
            J[:, j] = (4 * j1 - j2) / 3
        else:
            sh = s[j] * h[j]                   # offsets sh, 2sh, 3sh, 4sh
            j1 = (-3 * r0 + 4 * a - b) / (2 * sh)
            j2 = (-3 * r0 + 4 * b - d) / (4 * sh)
            J[:, j] = j1
        E[:, j] = j1 - j2
    return r0, J, E


@dataclass
class Uncertainty:
    """Result of :func:`analyse`: per-parameter table, correlation matrix,
    covariance (in the fitted coordinates), and the statistics used."""

    table: pd.DataFrame
    correlation: pd.DataFrame
    covariance: np.ndarray
    n: int
    n_eff: float
    s2: float
    singular_values: np.ndarray
    jacobian_error: float = 0.0  # ||E||_2 / largest singular value (scaled), 0 if not estimated
    covariance_bounded: np.ndarray | None = None  # as covariance, unresolved directions at the resolution limit

    def to_dict(self) -> dict:
        return {"n_samples": self.n, "n_eff": self.n_eff, "residual_variance": self.s2,
                "singular_values_scaled": self.singular_values.tolist(),
                "jacobian_error_scaled": self.jacobian_error,
                "parameters": self.table.to_dict(orient="records"),
                "correlation": {k: {kk: float(vv) for kk, vv in row.items()}
                                for k, row in self.correlation.to_dict(orient="index").items()},
                "undetermined": self.table.loc[~self.table["determined"], "parameter"].tolist(),
                **({} if self.covariance_bounded is None else
                   {"covariance_bounded": np.asarray(self.covariance_bounded).tolist()})}

    def to_markdown(self, title: str) -> str:
        from ..kpi import to_markdown

        t = self.table.copy()
        t["determined"] = np.where(t["determined"], "yes", "**NO**")
        cols = ["parameter", "value", "ci95 low", "ci95 high", "rel. half-width [%]", "sandwich / AR(1)",
                "max |corr|", "with", "determined", "why"]
        md = f"# {title}\n\n{to_markdown(t[cols], digits=4)}\n"
        md += (f"Linearised 95 % intervals (Student t, {self.n_eff - len(t):.0f} dof) from the Jacobian of the "
               f"residuals at the optimum; residual variance {self.s2:.4g} per sample over {self.n} samples, "
               f"effective sample size {self.n_eff:.0f} (AR(1) of the residuals), or from the batch-means sandwich "
               f"covariance over {BATCHES} batches (t with B - 1 dof), whichever is wider: the column "
               f"'sandwich / AR(1)' is their ratio, > 1 where a slow misfit the model cannot follow loads that "
               f"parameter. Intervals are statistical: a bias from a model or bench error that the data prefer "
               f"to the truth is not in them. Undetermined: half-width > "
               f"{REL_CI_MAX:.0%} of the value, |corr| > {CORR_MAX}, or a singular direction "
               f"(singular value ratio < {SV_MIN:g}) or one below the Jacobian's estimated error "
               f"({self.jacobian_error:.2g} of the largest singular value; central differences).\n\n"
               f"Scaled singular values: {', '.join(f'{v:.2g}' for v in self.singular_values)}."
               f"\n\nCorrelations:\n\n"
               + to_markdown(self.correlation.reset_index(names="parameter"), digits=2))
        return md


def batches(n: int, blocks: Sequence[int] | None = None, count: int = BATCHES) -> list[np.ndarray]:
    """Sample indices of ``count`` contiguous batches of an n-sample series
    made of records of lengths ``blocks`` (one record if None): each record
    gets batches in proportion to its length (at least one), so no batch
    spans two records."""
    blocks = [n] if blocks is None else [int(b) for b in blocks]
    if sum(blocks) != n or any(b < 1 for b in blocks):
        raise ValueError(f"record lengths {blocks} do not add up to the {n} residual samples")
    out, start = [], 0
    for b in blocks:
        k = max(1, min(b // 2, int(round(count * b / n))))
        out.extend(np.array_split(np.arange(start, start + b), k))
        start += b
    return out


def sandwich_covariance(Js: np.ndarray, r: np.ndarray, inv: np.ndarray, groups: list[np.ndarray]) -> np.ndarray:
    """Batch-means sandwich A^+ S A^+ (scaled coordinates): ``inv`` = A^+,
    S = B/(B-1) sum_b (g_b - mean g)(g_b - mean g)^T with g_b = J_b^T r_b.
    Centred: the thesis' objectives are L1, so sum_b g_b need not vanish."""
    G = np.array([Js[i].T @ r[i] for i in groups])
    Gc = G - G.mean(axis=0)
    B = len(groups)
    return inv @ (B / max(B - 1, 1) * Gc.T @ Gc) @ inv


def analyse(J: np.ndarray, r: np.ndarray, names: Sequence[str], x: np.ndarray,
            to_value: Callable[[int, np.ndarray], np.ndarray] | None = None, n_eff: float | None = None,
            rel_ci_max: float = REL_CI_MAX, corr_max: float = CORR_MAX, sv_min: float = SV_MIN,
            blocks: Sequence[int] | None = None, robust: bool = True,
            jac_error: np.ndarray | None = None) -> Uncertainty:
    """Covariance, 95 % intervals, correlations and identifiability flags of
    parameters ``x`` (fitted coordinates, e.g. genes) with residuals ``r``
    (n,) and Jacobian ``J`` (n, p). ``to_value(j, u)`` maps coordinate j to
    the physical value (intervals are mapped end point by end point, so a
    log-scaled parameter gets an asymmetric interval); identity if None.
    ``blocks``: lengths of the records concatenated in ``r`` (batches do not
    span two); ``robust=False`` reports the AR(1) intervals alone.
    ``jac_error`` (n, p): an estimate of J's error (:func:`central_jacobian`);
    directions with a singular value below its norm are not resolved."""
    J, r, x = np.asarray(J, float), np.asarray(r, float), np.asarray(x, float)
    n, p = J.shape
    to_value = to_value or (lambda j, u: u)
    n_eff = effective_sample_size(r) if n_eff is None else float(n_eff)
    n_eff = max(min(n_eff, n), p + 1.0)
    s2 = float(r @ r) / max(n - p, 1)
    # scale columns so the SVD compares directions, not units
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    Js = J / scale
    U, sv, Vt = np.linalg.svd(Js, full_matrices=False)
    rel_sv = sv / sv[0] if sv[0] > 0 else np.zeros_like(sv)
    floor = 0.0
    if jac_error is not None and sv[0] > 0:  # Weyl: each singular value is known to within ||E||_2
        floor = JAC_NOISE_FACTOR * float(np.linalg.norm(np.asarray(jac_error, float) / scale, 2)) / sv[0]
    keep = rel_sv > max(sv_min, floor)
    inv = (Vt[keep].T / sv[keep] ** 2) @ Vt[keep]          # (Js^T Js)^+
    cov = s2 * n / n_eff * inv / np.outer(scale, scale)
    # the same with every unresolved singular value raised to the resolution limit: a bounded covariance
    # for propagating to quantities the data do determine (calibration.identifiability)
    sv_lim = np.maximum(sv, max(sv_min, floor) * sv[0]) if sv[0] > 0 else np.ones_like(sv)
    cov_bounded = s2 * n / n_eff * ((Vt.T / sv_lim ** 2) @ Vt) / np.outer(scale, scale)
    null_dirs = Vt[~keep]
    var = np.diag(cov).copy()
    if null_dirs.size:  # the pseudo-inverse drops a singular direction: its parameters are unbounded
        var[np.any(np.abs(null_dirs) > NULL_LOADING, axis=0)] = np.inf
    sd = np.sqrt(np.maximum(var, 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(np.sqrt(np.diag(cov)), np.sqrt(np.diag(cov)))
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    tq = float(stats.t.ppf(0.975, n_eff - p))
    half_w = tq * sd                                       # AR(1) half-widths, fitted coordinates
    ratio = np.ones(p)
    if robust:
        groups = batches(n, blocks)
        if len(groups) >= 3:
            sd_rob = np.sqrt(np.maximum(np.diag(sandwich_covariance(Js, r, inv, groups)), 0)) / scale
            half_rob = float(stats.t.ppf(0.975, len(groups) - 1)) * sd_rob
            with np.errstate(invalid="ignore", divide="ignore"):
                ratio = np.where(half_w > 0, half_rob / half_w, 1.0)
            half_w = np.where(np.isfinite(sd), np.maximum(half_w, half_rob), np.inf)
    rows = []
    for j, name in enumerate(names):
        v = float(to_value(j, np.array(x[j])))
        lo, hi = (float(to_value(j, np.array(x[j] - half_w[j]))), float(to_value(j, np.array(x[j] + half_w[j])))) \
            if np.isfinite(half_w[j]) else (-np.inf, np.inf)
        half = 0.5 * (hi - lo)
        rel = half / abs(v) if v != 0 else np.inf
        oc = np.abs(corr[j]).copy()
        oc[j] = 0.0
        k = int(np.argmax(oc)) if p > 1 else j
        why = []
        if not np.isfinite(sd[j]):
            why.append("singular direction" if floor <= sv_min else
                       f"direction not resolved (singular value below the Jacobian's error, {floor:.1e} of the largest)")
        elif rel > rel_ci_max:
            why.append(f"CI half-width {rel:.0%} of value")
        if p > 1 and oc[k] > corr_max:
            why.append(f"|corr| {oc[k]:.3f} with {names[k]}")
        rows.append({"parameter": name, "value": v, "ci95 low": lo, "ci95 high": hi,
                     "rel. half-width [%]": 100 * rel, "std (fitted coord.)": float(sd[j]),
                     "sandwich / AR(1)": float(ratio[j]),
                     "max |corr|": float(oc[k]) if p > 1 else 0.0, "with": names[k] if p > 1 else "",
                     "determined": not why, "why": "; ".join(why)})
    return Uncertainty(pd.DataFrame(rows), pd.DataFrame(corr, index=list(names), columns=list(names)), cov, n,
                       n_eff, s2, rel_sv, floor, cov_bounded)


def other_optima(u: dict, ends: list[tuple[dict, float, float]], level: float = 0.95) -> dict:
    """Widen a local analysis (:meth:`Uncertainty.to_dict`, at the best
    point) by other local optima the multi-start search found: an end point
    (values by name, sum of squared residuals, eq. 6.x objective) whose
    residual sum exceeds the best's by less than s^2 (n / n_eff)
    chi2_p(level) lies inside the joint confidence region (Bates & Watts
    1988, sec. 2.1.3, in effective samples) although the linearised
    interval cannot reach it: the data cannot tell the two apart. Each
    parameter's interval is stretched to cover such optima; one that leaves
    the local interval marks the parameter as not determined."""
    u = {**u, "parameters": [dict(r) for r in u["parameters"]]}
    n, n_eff, s2, p = u["n_samples"], u["n_eff"], u["residual_variance"], len(u["parameters"])
    ssr_best = s2 * max(n - p, 1)
    limit = float(stats.chi2.ppf(level, p))
    inside = []
    for vals, ssr, j in ends:
        x = (ssr - ssr_best) / s2 * n_eff / n if s2 > 0 else np.inf
        moved = [r["parameter"] for r in u["parameters"]
                 if not r["ci95 low"] <= vals[r["parameter"]] <= r["ci95 high"]]
        if x <= limit and moved:
            inside.append({"values": dict(vals), "objective": j, "chi2": x, "outside_local_interval": moved})
    for r in u["parameters"]:
        for o in inside:
            v = o["values"][r["parameter"]]
            if not r["ci95 low"] <= v <= r["ci95 high"]:
                r["ci95 low"], r["ci95 high"] = min(r["ci95 low"], v), max(r["ci95 high"], v)
                r["determined"] = False
                why = f"another optimum inside the joint {level:.0%} region at {v:.4g}"
                r["why"] = "; ".join(filter(None, [r["why"], why]))
                r["rel. half-width [%]"] = 100 * 0.5 * (r["ci95 high"] - r["ci95 low"]) / abs(r["value"]) \
                    if r["value"] != 0 else np.inf
    u["other_optima"] = inside
    u["undetermined"] = [r["parameter"] for r in u["parameters"] if not r["determined"]]
    if inside and "markdown" in u:
        lines = [f"\nOther optima of the multi-start search inside the joint {level:.0%} confidence region "
                 f"(chi2 {limit:.1f} with {p} parameters, in effective samples): the data cannot tell them from "
                 f"the best, and the intervals above are widened to cover them.\n"]
        for o in inside:
            lines.append(f"- objective {o['objective']:.4g}, chi2 {o['chi2']:.1f}: "
                         + ", ".join(f"{k} {o['values'][k]:.4g}" for k in o["outside_local_interval"]))
        u["markdown"] = u["markdown"] + "\n".join(lines) + "\n"
    return u


METHOD = ("linearised least squares at the optimum: covariance s^2 (J^T J)^+ n / n_eff from the residual Jacobian, "
          "n_eff the AR(1) effective sample size of the residuals, or the batch-means sandwich covariance "
          f"({BATCHES} batches), whichever is wider; 95 % Student-t intervals (statistical only: a bias from a model "
          "or bench error is not in them); Jacobian by central differences, a direction whose singular value is "
          "below the Jacobian's estimated error is not resolved (unbounded intervals); widened to cover "
          "other optima of the multi-start polish inside the joint 95 % region (calibration.uncertainty)")


def _bound(x, sign: int) -> float:
    """An interval end or width read back from standard JSON (null = unbounded) as +-inf."""
    return json_number(x, sign * np.inf)


def summary(u: dict) -> dict:
    """The form every fit report uses (study ``fits.json``, ``dampertwin fit``
    ``fit.json``) of an :meth:`Uncertainty.to_dict`: per parameter its value,
    95 % interval, relative half-width, ``determined`` and why not; the
    undetermined list, the sample sizes and the correlations."""
    params = {r["parameter"]: {"value": r["value"], "ci95": [_bound(r["ci95 low"], -1), _bound(r["ci95 high"], 1)],
                               "rel_halfwidth": _bound(r["rel. half-width [%]"], 1) / 100.0,
                               "determined": bool(r["determined"]),
                               "why": r["why"]} for r in u["parameters"]}
    return {"method": METHOD, "n_samples": u["n_samples"], "n_eff": u["n_eff"], "parameters": params,
            "undetermined": list(u["undetermined"]), "correlation": u["correlation"],
            "other_optima": len(u.get("other_optima", []))}



def gauss_newton_ci(J: np.ndarray, residual: np.ndarray, names: list[str], values: np.ndarray,
                    jac_error: np.ndarray | None = None) -> dict:
    """Intervals of a fit from its residual Jacobian ``J`` (d residual / d
    parameter, physical units) at the optimum ``values``: :func:`analyse` in
    the report form of :func:`summary`, plus each parameter's standard
    deviation [its unit]. ``jac_error``: an estimate of J's error
    (directions below it are not resolved)."""
    u = analyse(J, residual, list(names), np.asarray(values, float), jac_error=jac_error)
    out = summary(u.to_dict())
    for row in u.table.to_dict(orient="records"):
        out["parameters"][row["parameter"]]["std"] = row["std (fitted coord.)"]  # coordinates = physical here
        out["parameters"][row["parameter"]]["sandwich / AR(1)"] = row["sandwich / AR(1)"]
    out["covariance_bounded"] = np.asarray(u.covariance_bounded).tolist()
    return out
