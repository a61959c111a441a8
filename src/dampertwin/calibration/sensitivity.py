"""Time-resolved grouped first-order Sobol indices (thesis 7.1, L1434-1436,
L1527-1536) and the sensitivity-weighted objective of eq. 7.1.

The thesis runs a variance-based sensitivity analysis of the simulated
damper force at *every time point* of the training signal, with the
parameters grouped by valve (4 groups), 32 base samples of SALib's grouped
Saltelli design with second order: 32 x (2 x 4 + 2) = 320 simulations.

- :func:`sample` draws the design with SALib (``SALib.sample.sobol``, the
  Saltelli scheme on a scrambled Sobol' sequence, seeded) in gene space
  [0, 1] and maps it to parameter values through the fitted quantities'
  :class:`~dampertwin.calibration.ga.ParamSpec` (lin / log).
- :func:`first_order` is the Saltelli et al. (2010) first-order estimator
  SALib's ``analyze.sobol`` uses (outputs standardised over all runs, index
  = mean(B (AB_j - A)) / var([A; B])) vectorised with numpy over all time
  points at once, with SALib's bootstrap confidence (same resamples when
  given the same seed) and a mask for instants whose output does not vary
  between runs (there the index is undefined: NaN, weight 0).
- :func:`run_converged` doubles the base sample N (up to a cap) until the
  weight curves change by less than a tolerance between N and 2 N
  (:func:`weight_change`), reusing the runs of N: SALib's design of 2 N
  starts with the design of N (:func:`is_prefix`).
- :func:`weights` turns the index curves into eq.-7.1 weights: by default
  the lower bound of the bootstrap interval S1 - S1_conf (an instant where
  the group's influence is not established weighs 0), clip, optional
  moving-average smoothing, per-group normalisation (all named settings,
  :class:`WeightSettings`).
- :func:`weighted_integrals` is eq. 7.1,
  J_i = int_0^T I_i(t) |F_test(t) - F_sim(Theta_i, t)| dt, for a batch of
  simulations and all groups at once (trapezoid rule).

Nothing here knows the damper: any model output (n_runs x n_times) works.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import pandas as pd
from scipy.stats import norm

from ..errors import UserError
from .ga import ParamSpec

EPS = np.finfo(float).eps
ROUND_OFF = 1e-12  # [-] smoothed weights below this are round-off (indices are O(0.01-1)): set to 0


@dataclass(frozen=True)
class Group:
    """A parameter group (thesis: all parameters of one valve)."""

    name: str
    specs: tuple[ParamSpec, ...]


def salib_problem(groups: Sequence[Group]) -> dict:
    """SALib problem in gene space (every gene in [0, 1]) with groups."""
    names, grp = [], []
    for g in groups:
        if not g.specs:
            raise UserError(f"sensitivity group {g.name!r} has no parameters")
        for s in g.specs:
            names.append(s.key)
            grp.append(g.name)
    if len(set(names)) != len(names):
        raise UserError(f"sensitivity groups share parameters: {sorted(n for n in set(names) if names.count(n) > 1)}")
    return {"num_vars": len(names), "names": names, "bounds": [[0.0, 1.0]] * len(names), "groups": grp}


def runs_needed(n_base: int, n_groups: int, second_order: bool = True) -> int:
    """Simulations of a grouped Saltelli design: N (2G + 2) with second
    order, N (G + 2) without (thesis: 32 x 10 = 320)."""
    return n_base * (2 * n_groups + 2 if second_order else n_groups + 2)


def sample(groups: Sequence[Group], n_base: int, seed: int, second_order: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Grouped Saltelli design (SALib, scrambled Sobol', seeded). Returns
    (genes [n, k] in [0, 1], values [n, k] in SI) with n = runs_needed(...)."""
    from SALib.sample import sobol as sobol_sample

    if n_base < 2 or n_base & (n_base - 1):
        raise UserError(f"sensitivity: n_base = {n_base}; the Sobol' sequence needs a power of 2 (thesis: 32)")
    problem = salib_problem(groups)
    G = np.asarray(sobol_sample.sample(problem, n_base, calc_second_order=second_order, scramble=True,
                                       seed=int(seed)), float)
    specs = [s for g in groups for s in g.specs]
    X = np.column_stack([s.to_value(G[:, j]) for j, s in enumerate(specs)])
    return G, X


@dataclass
class SobolResult:
    """First-order indices S1[g, t] of each group at each instant, their
    bootstrap confidence half-width (SALib's ``S1_conf``: z * std of the
    resampled estimates) and the mask of instants without output variance."""

    groups: list[str]
    S1: np.ndarray  # (G, T), NaN where masked
    S1_conf: np.ndarray  # (G, T), NaN where masked
    masked: np.ndarray  # (T,) bool
    conf_level: float = 0.95
    meta: dict = field(default_factory=dict)

    @property
    def lower(self) -> np.ndarray:
        return self.S1 - self.S1_conf

    @property
    def upper(self) -> np.ndarray:
        return self.S1 + self.S1_conf

    def to_frame(self, t: np.ndarray) -> pd.DataFrame:
        """Tidy: one row per (group, instant), unit-suffixed columns."""
        G, T = self.S1.shape
        return pd.DataFrame({
            "time [s]": np.tile(np.asarray(t, float), G),
            "group": np.repeat(np.array(self.groups, dtype=object), T),
            "S1 [-]": self.S1.ravel(), "S1 conf [-]": self.S1_conf.ravel(),
            "S1 lower [-]": self.lower.ravel(), "S1 upper [-]": self.upper.ravel(),
            "masked": np.tile(self.masked, G),
        })


def _split(Y: np.ndarray, D: int, second_order: bool):
    """SALib's ordering of a Saltelli design: per base sample A, AB_1..AB_D,
    (BA_1..BA_D), B. Y is (n_runs, T); returns A, B (N, T), AB (N, D, T)."""
    step = 2 * D + 2 if second_order else D + 2
    if Y.shape[0] % step:
        raise ValueError(f"{Y.shape[0]} runs is not a multiple of {step} (grouped Saltelli design with "
                         f"{D} groups, second_order={second_order})")
    Z = Y.reshape(Y.shape[0] // step, step, Y.shape[1])
    return Z[:, 0], Z[:, step - 1], Z[:, 1:D + 1]


def _s1(A, AB, B):
    """Saltelli 2010 first-order estimator, leading axis = samples; A, B
    (N, ...), AB (N, D, ...) -> (D, ...)."""
    var = np.var(np.concatenate([A, B], axis=0), axis=0)
    num = np.mean(B[:, None] * (AB - A[:, None]), axis=0)
    return np.divide(num, var, out=np.zeros_like(num), where=var > EPS)


def first_order(Y: np.ndarray, n_groups: int, *, second_order: bool = True, num_resamples: int = 100,
                conf_level: float = 0.95, seed: int | None = None, mask_rel_std: float = 1e-9,
                chunk: int = 2048) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time-resolved first-order indices of a grouped Saltelli design.

    ``Y`` is (n_runs, T): the model output of every run of :func:`sample`
    at every instant. Each instant is treated exactly as
    ``SALib.analyze.sobol.analyze(problem, Y[:, t], seed=seed)`` treats a
    scalar output (standardised over all runs; bootstrap with the same
    resample indices), but all instants at once. Instants whose output std
    over the runs is below ``mask_rel_std`` times the largest std over time
    (or not finite) are masked (NaN). Returns (S1 (G, T), S1_conf (G, T),
    masked (T,))."""
    Y = np.asarray(Y, float)
    if Y.ndim != 2:
        raise ValueError(f"Y must be (runs, instants), got shape {Y.shape}")
    D = int(n_groups)
    step = 2 * D + 2 if second_order else D + 2
    N = Y.shape[0] // step
    finite = np.all(np.isfinite(Y), axis=0)
    sd = np.where(finite, np.nanstd(np.where(np.isfinite(Y), Y, np.nan), axis=0), 0.0)
    scale = float(sd.max()) if sd.size and np.any(sd > 0) else 0.0
    masked = ~finite | (sd <= mask_rel_std * scale) | (sd <= EPS)
    # SALib draws with np.random.default_rng(seed).integers when seed is truthy (same resamples here);
    # it leaves seed 0 / None unseeded, this module never does: every draw is seeded
    rng = np.random.default_rng(seed if seed else 0)
    r = rng.integers(N, size=(N, num_resamples))
    z = norm.ppf(0.5 + conf_level / 2)
    T = Y.shape[1]
    S1 = np.full((D, T), np.nan)
    conf = np.full((D, T), np.nan)
    live = np.flatnonzero(~masked)
    for lo in range(0, len(live), chunk):
        cols = live[lo:lo + chunk]
        y = Y[:, cols]
        y = (y - y.mean(axis=0)) / y.std(axis=0)  # SALib standardises the output (over all runs)
        A, B, AB = _split(y, D, second_order)
        S1[:, cols] = _s1(A, AB, B)
        # bootstrap: resample the base samples (rows) with SALib's indices r (N, R)
        Ar, Br, ABr = A[r], B[r], AB[r]  # (N, R, c), (N, R, c), (N, R, D, c)
        var = np.var(np.concatenate([Ar, Br], axis=0), axis=0)  # (R, c)
        num = np.mean(Br[:, :, None] * (ABr - Ar[:, :, None]), axis=0)  # (R, D, c)
        Sr = np.divide(num, var[:, None], out=np.zeros_like(num), where=var[:, None] > EPS)
        conf[:, cols] = z * Sr.std(axis=0, ddof=1)
    return S1, conf, masked


def analyse(Y: np.ndarray, groups: Sequence[Group] | Sequence[str], **kw) -> SobolResult:
    """:func:`first_order` wrapped in a :class:`SobolResult`."""
    names = [g.name if isinstance(g, Group) else str(g) for g in groups]
    S1, conf, masked = first_order(Y, len(names), **kw)
    return SobolResult(names, S1, conf, masked, kw.get("conf_level", 0.95))


def _evaluate(output: Callable[[np.ndarray], np.ndarray], X: np.ndarray) -> np.ndarray:
    Y = np.asarray(output(X), float)
    if Y.ndim != 2 or Y.shape[0] != len(X):
        raise ValueError(f"sensitivity output must be (runs={len(X)}, instants), got {Y.shape}")
    return Y


def _analyse_blocks(Y: np.ndarray, groups, n_base: int, seed: int, second_order: bool, num_resamples: int,
                    conf_level: float, mask_rel_std: float) -> tuple[SobolResult, np.ndarray]:
    """Drop the base-sample blocks with a failed run, analyse the rest."""
    step = len(Y) // n_base
    ok_run = np.all(np.isfinite(Y), axis=1)
    ok_block = ok_run.reshape(n_base, step).all(axis=1)
    if ok_block.sum() < 2:
        raise UserError(f"sensitivity: {int((~ok_run).sum())} of {len(Y)} simulations failed, leaving "
                        f"{int(ok_block.sum())} complete base samples of {n_base}; the estimator needs at least 2 "
                        f"(narrow the search windows or raise the wall-time cap)")
    Yk = Y.reshape(n_base, step, -1)[ok_block].reshape(-1, Y.shape[1])
    res = analyse(Yk, groups, second_order=second_order, num_resamples=num_resamples, conf_level=conf_level,
                  seed=seed, mask_rel_std=mask_rel_std)
    res.meta.update({"runs": len(Y), "n_base": n_base, "seed": seed, "second_order": second_order,
                     "num_resamples": num_resamples, "masked_instants": int(res.masked.sum()),
                     "failed_runs": int((~ok_run).sum()), "dropped_base_samples": int((~ok_block).sum())})
    return res, Yk


def run(groups: Sequence[Group], output: Callable[[np.ndarray], np.ndarray], n_base: int, seed: int, *,
        second_order: bool = True, num_resamples: int = 100, conf_level: float = 0.95,
        mask_rel_std: float = 1e-9) -> tuple[SobolResult, np.ndarray]:
    """Sample, evaluate ``output(values [n, k]) -> (n, T)`` (any model
    output; one batch call), analyse. A run whose output is not finite (a
    failed simulation) invalidates its base sample's block of the Saltelli
    design (A, AB_j, BA_j, B); such blocks are left out, the estimate uses
    the remaining base samples (independent draws, so it stays unbiased),
    and ``result.meta`` says how many were dropped; fewer than 2 complete
    blocks is an error. Returns (result, Y) with Y the complete blocks."""
    _, X = sample(groups, n_base, seed, second_order)
    return _analyse_blocks(_evaluate(output, X), groups, n_base, seed, second_order, num_resamples, conf_level,
                           mask_rel_std)


def is_prefix(groups: Sequence[Group], n_base: int, seed: int, second_order: bool = True) -> bool:
    """Whether SALib's design of 2 N starts with the design of N, row for
    row (same seed): the Sobol' points are drawn in sequence (the
    scrambling is fixed by the seed, no skip) and the Saltelli rows are laid
    out base point by base point, so the N-design's runs can be reused."""
    _, X = sample(groups, n_base, seed, second_order)
    _, X2 = sample(groups, 2 * n_base, seed, second_order)
    return bool(np.array_equal(X2[:len(X)], X))


def weight_change(W_new: np.ndarray, W_old: np.ndarray, live: np.ndarray) -> np.ndarray:
    """Change of each group's weight curve between two sample sizes (G,):
    the share of its weight that moves between instants,
    0.5 sum_t |w_2N / sum w_2N - w_N / sum w_N| over the instants ``live``
    in both, in [0, 1]. A curve's scale does not count: eq. 7.1 scaled by a
    constant ranks a GA's members alike (steady-state selection keeps the
    best), so only where the weight sits in time changes what the group's
    GA minimises. A group with no weight at either size changes by 0; one
    with weight at one size only, by 1."""
    Wn = np.asarray(W_new, float)[:, live]
    Wo = np.asarray(W_old, float)[:, live]
    sn, so = Wn.sum(axis=1, keepdims=True), Wo.sum(axis=1, keepdims=True)
    pn = np.divide(Wn, sn, out=np.zeros_like(Wn), where=sn > 0)
    po = np.divide(Wo, so, out=np.zeros_like(Wo), where=so > 0)
    d = 0.5 * np.abs(pn - po).sum(axis=1)
    one = (sn[:, 0] > 0) != (so[:, 0] > 0)
    return np.where(one, 1.0, d)


def run_converged(groups: Sequence[Group], output: Callable[[np.ndarray], np.ndarray], n_base: int, n_max: int,
                  tol: float, seed: int, weigh: Callable[[SobolResult], np.ndarray], *, second_order: bool = True,
                  num_resamples: int = 100, conf_level: float = 0.95,
                  mask_rel_std: float = 1e-9) -> tuple[SobolResult, np.ndarray, dict]:
    """:func:`run` with the base sample N doubled (n_base, 2 n_base, ...,
    at most ``n_max``) until every group's weight curve (``weigh(result)``
    -> (G, T)) changes by less than ``tol`` between N and 2 N
    (:func:`weight_change`, max over the groups). The runs of N are reused
    when the design of 2 N starts with them (:func:`is_prefix`; only the new
    rows are simulated), else all rows are run again. Returns the result of
    the last N, its Y, and a record: the N sequence, the runs simulated,
    the change per doubling and ``converged`` (True / False; None when
    n_max = n_base, i.e. no check)."""
    if n_max < n_base or n_max & (n_max - 1):
        raise UserError(f"sensitivity: n_max = {n_max}; expected a power of 2 >= n_base = {n_base}")
    if not tol > 0:
        raise UserError(f"sensitivity: convergence tol = {tol!r}; expected > 0")
    kw = dict(second_order=second_order, num_resamples=num_resamples, conf_level=conf_level,
              mask_rel_std=mask_rel_std)
    X_old = Y_all = None
    W_old = live_old = None
    n, sims, changes, reused = n_base, 0, [], []
    while True:
        _, X = sample(groups, n, seed, second_order)
        k = 0 if X_old is None or not np.array_equal(X[:len(X_old)], X_old) else len(X_old)
        Y_new = _evaluate(output, X[k:])
        sims += len(X) - k
        reused.append(k)
        Y_all = Y_new if k == 0 else np.vstack([Y_all, Y_new])
        res, Yk = _analyse_blocks(Y_all, groups, n, seed, **kw)
        W = weigh(res)
        live = ~res.masked
        if W_old is not None:
            changes.append([float(c) for c in weight_change(W, W_old, live & live_old)])
            if max(changes[-1]) < tol:
                break
        if 2 * n > n_max:
            break
        X_old, W_old, live_old, n = X, W, live, 2 * n
    seq = [n_base * 2 ** i for i in range(len(reused))]
    conv = None if len(seq) == 1 else bool(max(changes[-1]) < tol)
    record = {"n_sequence": seq, "n_final": n, "n_max": n_max, "tol": tol, "runs_simulated": sims,
              "runs_reused": reused, "change_per_doubling": [max(c) for c in changes],
              "change_per_doubling_per_group": [dict(zip(res.groups, c)) for c in changes], "converged": conv,
              "metric": "max over groups of 0.5 sum_t |w_2N / sum w_2N - w_N / sum w_N| (the share of the weight "
                        "that moves between instants; instants unmasked at both N)"}
    res.meta.update({"runs_simulated": sims, "converged": conv})
    return res, Yk, record


# ------------------------------------------------------------ weights (eq. 7.1)
@dataclass(frozen=True)
class WeightSettings:
    """Clean-up of index curves into eq.-7.1 weights.

    - ``rule``: which value of the index an instant is weighted by:
      ``lower_bound`` (default) = S1 - S1_conf, the lower end of SALib's
      bootstrap confidence interval: the share of the force variance the
      group is shown (at ``conf_level``) to have. An instant whose interval
      reaches 0 (the group's influence there is not established) weighs 0;
      of two instants with the same estimate, the sharper one weighs more.
      The estimate alone (``estimate``, the thesis as written) weights the
      estimator's noise like a signal: at N = 32, 11-37 % of the instants
      had S1 < 0 and up to 26 % S1 > 1 (issue 37);
    - ``clip``: [lo, hi] the values are clipped to (a first-order index
      is in [0, 1]);
    - ``smooth_s``: centred moving-average window [s] (0: none), against
      estimator noise between neighbouring instants;
    - ``normalise``: per group, ``max`` (each weight curve peaks at 1),
      ``mean`` (mean 1 over time) or ``none``;
    - masked instants (no output variance) weigh 0."""

    clip: tuple[float, float] = (0.0, 1.0)
    smooth_s: float = 0.0
    normalise: str = "max"
    rule: str = "lower_bound"

    KEYS = ("rule", "clip", "smooth_s", "normalise")

    @classmethod
    def from_config(cls, c, where: str = "conf/calibration/approach2.yaml: weights") -> "WeightSettings":
        if not isinstance(c, dict) and not hasattr(c, "get"):
            raise UserError(f"{where}: expected a mapping with {', '.join(cls.KEYS)}")
        unknown = set(c) - set(cls.KEYS)
        if unknown:
            raise UserError(f"{where}: unknown key(s) {sorted(unknown)}; expected {', '.join(cls.KEYS)}")
        clip = list(c.get("clip", [0.0, 1.0]))
        if len(clip) != 2 or not clip[0] < clip[1]:
            raise UserError(f"{where}.clip: expected [lo, hi] with lo < hi, got {clip!r}")
        sm = c.get("smooth_s", 0.0)
        if not isinstance(sm, (int, float)) or sm < 0:
            raise UserError(f"{where}.smooth_s: expected a window >= 0 [s], got {sm!r}")
        nm = c.get("normalise", "max")
        if nm not in ("max", "mean", "none"):
            raise UserError(f"{where}.normalise: expected max, mean or none, got {nm!r}")
        rule = c.get("rule", "lower_bound")
        if rule not in ("lower_bound", "estimate"):
            raise UserError(f"{where}.rule: expected lower_bound or estimate, got {rule!r}")
        return cls((float(clip[0]), float(clip[1])), float(sm), str(nm), str(rule))


def weights(S1: np.ndarray, t: np.ndarray, settings: WeightSettings = WeightSettings(),
            conf: np.ndarray | None = None) -> np.ndarray:
    """Index curves (G, T) -> weights (G, T) >= 0 (vectorised). With the
    ``lower_bound`` rule the confidence half-widths ``conf`` (G, T) are
    needed (S1_conf of :func:`first_order`)."""
    from scipy.ndimage import uniform_filter1d

    S = np.asarray(S1, float)
    if settings.rule == "lower_bound":
        if conf is None:
            raise ValueError("weights: the lower_bound rule needs the confidence half-widths (conf)")
        S = S - np.asarray(conf, float)
    W = np.clip(np.nan_to_num(S, nan=0.0), *settings.clip)
    W = np.maximum(W, 0.0)
    if settings.smooth_s > 0:
        dt = float(np.median(np.diff(t)))
        n = max(1, int(round(settings.smooth_s / dt)))
        if n > 1:
            W = uniform_filter1d(W, n, axis=1, mode="nearest")
            W[W < ROUND_OFF] = 0.0  # the filter's running sum leaves ~1e-16 far from any weight: exact 0 there
    if settings.normalise != "none":
        ref = W.max(axis=1) if settings.normalise == "max" else W.mean(axis=1)
        W = np.divide(W, ref[:, None], out=np.zeros_like(W), where=ref[:, None] > 0)
    return W


def result_weights(res: SobolResult, t: np.ndarray, settings: WeightSettings = WeightSettings()) -> np.ndarray:
    """:func:`weights` of a :class:`SobolResult` (its S1 and S1_conf)."""
    return weights(res.S1, t, settings, res.S1_conf)


def unweighted_groups(groups: Sequence[str], W: np.ndarray) -> list[str]:
    """Groups whose weight curve is 0 at every instant (eq. 7.1 would score
    every member of their GA 0)."""
    return [g for g, w in zip(groups, np.asarray(W, float)) if not np.any(w > 0)]


def weighted_integrals(abs_residual: np.ndarray, quad_weights: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Eq. 7.1 for a batch: J[m, g] = sum_t W[g, t] |r[m, t]| w_t with w_t
    the trapezoid weights [s]; NaN rows (failed runs) stay NaN. Each row is
    summed on its own (:func:`row_integrals`): a member's value does not
    depend on the batch it is scored in (a population split over a cluster)."""
    Wq = np.asarray(W, float) * np.asarray(quad_weights, float)[None, :]
    R = np.asarray(abs_residual, float)
    return np.column_stack([row_integrals(R, w) for w in Wq]) if len(Wq) else np.zeros((len(R), 0))


def row_integrals(R: np.ndarray, w: np.ndarray) -> np.ndarray:
    """sum_t R[m, t] w[t] for each row m, row by row (numpy's pairwise sum
    along the row), so a row's value is the same bits in any batch (a
    matrix product's blocking depends on the batch size)."""
    return (np.ascontiguousarray(R, float) * np.asarray(w, float)[None, :]).sum(axis=1)


def figure(t: np.ndarray, res: SobolResult, W: np.ndarray, signal: np.ndarray | None = None,
           signal_label: str = "force [N]", beside: dict | None = None, beside_label: str = "",
           focus: tuple[float, float] | None = None, title: str = "First-order Sobol index (thesis fig. 7.6)"):
    """Like thesis fig. 7.6 a-d: one row per group with its index S1(t),
    the bootstrap band (S1 -/+ S1_conf), its weight curve ``W`` and, on the
    right axis, ``beside[group]`` (e.g. that valve's opening); the record's
    ``signal`` on top. Left column the whole record, right column the
    ``focus`` window [s] (t0, t1), if given."""
    import matplotlib.pyplot as plt

    G = len(res.groups)
    top = 1 if signal is not None else 0
    cols = 2 if focus is not None else 1
    fig, axes = plt.subplots(G + top, cols, figsize=(7.5 * cols, 2.3 * (G + top) + 0.8), sharex="col",
                             squeeze=False, constrained_layout=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for c in range(cols):
        m = np.ones(len(t), bool) if c == 0 else (t >= focus[0]) & (t <= focus[1])
        tm = t[m]
        if top:
            ax = axes[0, c]
            ax.plot(tm, np.asarray(signal)[m], "k", lw=0.6)
            ax.set(ylabel=signal_label, title="whole record" if c == 0 else "focus: highest force")
            ax.grid(alpha=0.3)
        for i, g in enumerate(res.groups):
            ax = axes[top + i, c]
            col = colours[i % len(colours)]
            if beside is not None and g in beside:
                ax2 = ax.twinx()
                ax2.fill_between(tm, 0.0, np.asarray(beside[g])[m], color="0.6", alpha=0.35, lw=0, step="mid")
                ax2.set_ylabel(beside_label, fontsize=8, color="0.4")
                ax2.tick_params(labelsize=7, colors="0.4")
            ax.fill_between(tm, np.clip(res.lower[i][m], -0.2, 1.2), np.clip(res.upper[i][m], -0.2, 1.2),
                            color=col, alpha=0.25, lw=0, label="S1 -/+ conf")
            ax.plot(tm, res.S1[i][m], color=col, lw=0.7, label="S1")
            ax.plot(tm, W[i][m], color="k", lw=0.8, ls="--", label="weight (eq. 7.1)")
            ax.set(ylim=(-0.2, 1.2), ylabel=f"{g}\n[-]")
            ax.set_zorder(3)
            ax.patch.set_visible(False)
            ax.grid(alpha=0.3)
            if i == 0 and c == 0:
                ax.legend(loc="upper right", fontsize=7, ncol=3)
        axes[-1, c].set(xlabel="time [s]")
    fig.suptitle(title, fontsize=10)
    return fig


__all__ = ["Group", "SobolResult", "WeightSettings", "salib_problem", "runs_needed", "sample", "first_order",
           "analyse", "run", "run_converged", "is_prefix", "weight_change", "weights", "result_weights", "unweighted_groups", "weighted_integrals", "row_integrals", "figure"]
