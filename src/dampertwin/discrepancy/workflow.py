"""Find / separate / name / add: the discrepancy workflow on prepared units.

All simulations of one step run as one ``simulate_batch`` per record (a
population of designs), so a step costs (number of designs) x (records).
No files are read or written here (see ``entry``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..calibration.ga import ParamSpec
from ..design import Design, DesignError
from ..simulation import simulate_batch
from . import features as F


# ------------------------------------------------------------------ parameters
def FitParam(key: str, lo: float, hi: float, start: float) -> ParamSpec:  # noqa: N802  (the refits' name)
    """A fitted parameter in normalised coordinates u in [0, 1] over its
    bounds (logarithmic when the bounds are positive and span > 2 decades):
    the calibration core's :class:`~dampertwin.calibration.ga.ParamSpec`."""
    return ParamSpec.auto(key, lo, hi, start)


@dataclass
class Candidate:
    """An effect that may be missing: switch(es) + parameters at a typical magnitude."""

    name: str                       # effect name ("a+b" for a pair)
    effects: list
    params: list                    # FitParam of the effect's C parameters
    typical: dict                   # key -> typical value (C and F parameters)

    def overrides(self) -> dict:
        return {**{f"effects.{e}": True for e in self.effects}, **self.typical}


def design_value(design: Design, key: str):
    return design[key]


def calibration_params(design: Design, cfg: dict) -> list[FitParam]:
    """The calibration pool of the config: existing scalar parameters with their bounds."""
    out = []
    extra = cfg.get("calibration_bounds", {}) or {}
    for key in cfg.get("calibration_pool", []):
        try:
            p = design.param(key)
        except KeyError:
            continue
        if isinstance(p.value, tuple):
            continue
        b = p.bounds if p.bounds is not None else extra.get(key)
        if b is None or isinstance(b[0], (list, tuple)):
            continue
        lo, hi = float(b[0]), float(b[1])
        if not lo < hi:
            continue
        out.append(FitParam(key, lo, hi, float(p.value)))
    return out


def _lacking(design: Design) -> tuple[str, ...]:
    """Effects of parts the design's architecture has no part for (a passive damper's active-valve effects)."""
    from ..design.architecture import ACTIVE_VALVE_EFFECTS

    return ACTIVE_VALVE_EFFECTS if design.pq_map is None else ()


def catalogue(design: Design, cfg: dict) -> list[Candidate]:
    """Candidates, data-driven: every effect with ``effect_parameters`` that is
    off in the design (fit = its C entries, magnitude = ``typical``), plus the
    thesis effects switched off in the design (conf/discrepancy.yaml
    ``thesis_effects``: their fit parameters)."""
    cands: dict[str, Candidate] = {}
    if hasattr(design, "effect_parameters"):
        by: dict[str, list] = {}
        for e in design.effect_parameters():
            by.setdefault(e.effect, []).append(e)
        for eff, entries in by.items():
            if design.effects.get(eff, False) or eff in _lacking(design):
                continue
            params = [FitParam(e.key, float(e.bounds[0]), float(e.bounds[1]), float(e.typical))
                      for e in entries if e.type == "C" and e.bounds is not None]
            cands[eff] = Candidate(eff, [eff], params, {e.key: float(e.typical) for e in entries})
    for eff, spec in (cfg.get("thesis_effects") or {}).items():
        if eff in cands or eff not in design.effects or design.effects[eff] or eff in _lacking(design):
            continue
        params, typ = [], {}
        for key, s in ((spec or {}).get("params") or {}).items():
            try:
                design[key]
            except KeyError:
                continue  # e.g. constants.leak_gap after the effect_parameters API replaced it
            lo, hi = (float(x) for x in s["bounds"])
            params.append(FitParam(key, lo, hi, float(s["typical"])))
            typ[key] = float(s["typical"])
        cands[eff] = Candidate(eff, [eff], params, typ)
    return list(cands.values())


# ------------------------------------------------------------------ evaluation
@dataclass
class Row:
    """Simulated features of one design: per unit, [cycles, features]."""

    pcs: list

    @property
    def S(self) -> np.ndarray:
        return np.concatenate([p.mean(axis=0) for p in self.pcs])

    @property
    def ok(self) -> bool:
        return all(np.all(np.isfinite(p)) for p in self.pcs)


@dataclass
class Problem:
    """The prepared units, the feature config and the per-case design variants."""

    units: list
    fcfg: dict
    variant_of: dict = field(default_factory=dict)   # case -> Variant (or None)
    progress: bool = True
    n_sims: int = 0
    W: np.ndarray | None = None
    failures: list = field(default_factory=list)
    executor: object = None          # concurrent.futures executor for the records (None: in process)

    @property
    def labels(self):
        return [(u.test, u.case, u.run, ch, ph) for u in self.units for ch, ph in u.labels]

    @property
    def sigma(self) -> np.ndarray:
        return np.concatenate([u.sigma for u in self.units])

    def set_noise(self, base: Row) -> None:
        """Noise model from the residual scatter of the design under test
        (features.noise), the records of one fold coupled by the transducer
        chains' shared gain errors (features.shared_covariance). Whitened per
        fold: a training chi^2 never sees held-out data and vice versa (the
        two folds' gain nuisances are treated as independent)."""
        for u, pc in zip(self.units, base.pcs):
            u.sigma, u.white = F.noise(u, self.fcfg, pc)
        sizes = [len(u.labels) for u in self.units]
        starts = np.concatenate([[0], np.cumsum(sizes)])
        W = np.zeros((starts[-1], starts[-1]))
        for fold in dict.fromkeys(getattr(u, "fold", "train") for u in self.units):
            members = [i for i, u in enumerate(self.units) if getattr(u, "fold", "train") == fold]
            idx = np.concatenate([np.arange(starts[i], starts[i + 1]) for i in members])
            C = F.shared_covariance([self.units[i] for i in members])
            W[np.ix_(idx, idx)] = np.linalg.inv(np.linalg.cholesky(C))
        self.W = W

    def measured(self, boot: list | None = None) -> np.ndarray:
        return np.concatenate([u.measured_features(None if boot is None else boot[i]) for i, u in enumerate(self.units)])

    def mask(self, fold: str | None) -> np.ndarray:
        return np.concatenate([np.full(len(u.labels), fold is None or u.fold == fold) for u in self.units])

    def n_eff(self, fold: str | None = None) -> int:
        """Effective sample size: cycles (segments), not samples."""
        return int(sum(u.n_cycles for u in self.units if fold is None or u.fold == fold))

    def simulate(self, designs: list, label: str = "simulate", keep: bool = False):
        """Simulated features (a Row per design; NaN for failed members);
        with ``keep`` also the simulated signals per unit. Records run as
        separate tasks on ``executor`` when one is set (a process pool:
        a refit step simulates ONE design, which a batch alone cannot spread
        over the cores), longest first; the results are the same numbers."""
        from ..progress import progress as tqdm

        n = len(self.units)
        args = [(u, self.fcfg, self.variant_of.get(u.case), designs, keep) for u in self.units]
        done: list = [None] * n
        bar = tqdm(total=n, desc=f"{label} ({len(designs)} designs)", disable=not self.progress, leave=False)
        if self.executor is not None and n > 1:
            from concurrent.futures import as_completed

            order = sorted(range(n), key=lambda i: -self.units[i].t.size)   # longest record first
            futs = {self.executor.submit(simulate_unit, *args[i]): i for i in order}
            for f in as_completed(futs):
                done[futs[f]] = f.result()
                bar.update()
        else:
            for i in range(n):
                done[i] = simulate_unit(*args[i])
                bar.update()
        bar.close()
        pcs, kept = [], []
        for rows, sig, n_sims, failures in done:
            pcs.append(rows)
            kept.append(sig)
            self.n_sims += n_sims
            self.failures.extend(failures)
        out = [Row([pcs[i][j] for i in range(n)]) for j in range(len(designs))]
        return (out, kept) if keep else out

    def residual(self, row: Row, boot: list | None = None) -> np.ndarray:
        """measured - simulated features (over the resampled cycles ``boot``)."""
        if boot is None:
            return self.measured() - row.S
        return np.concatenate([u.per_cycle[b].mean(axis=0) - p[b].mean(axis=0)
                               for u, p, b in zip(self.units, row.pcs, boot)])

    def z(self, row: Row, boot: list | None = None) -> np.ndarray:
        """Whitened residuals (noise, gain and offset nuisances of the bench accounted for)."""
        r = self.residual(row, boot)
        if not np.all(np.isfinite(r)):
            return np.full_like(r, np.nan)
        return self.W @ r

    def zdiag(self, row: Row) -> np.ndarray:
        """Residual / noise level, feature by feature (for the localised map)."""
        return self.residual(row) / self.sigma


def simulate_unit(u, fcfg: dict, var, designs: list, keep: bool = False):
    """One record for a population of designs (also a worker task: no I/O).
    Returns (feature rows per design, NaN for failed members; simulated
    signals per design when ``keep``; simulations run; failure messages)."""
    def record_design(d):  # the case's variant, then what the record itself sets (friction test: precharge)
        d = var.apply(d) if var is not None else d
        return d.with_overrides(u.overrides) if u.overrides else d

    ds, bad = [], []
    for d in designs:
        try:
            ds.append(record_design(d))
            bad.append(False)
        except (DesignError, ValueError):
            ds.append(record_design(designs[0]))
            bad.append(True)
    fs = 1.0 / float(np.mean(np.diff(u.t)))
    # one batch per pattern of effect switches (effects with states must be alike in a batch)
    groups: dict = {}
    for j, d in enumerate(ds):
        groups.setdefault(tuple(sorted(d.effects.items())), []).append(j)
    rows = [np.full(u.per_cycle.shape, np.nan) for _ in ds]
    sig = [None] * len(ds)
    n_sims, failures = 0, []
    for members in groups.values():
        try:
            _, ch, status = simulate_batch([ds[j] for j in members], u.excitation, u.configuration,
                                           current=u.current, rate=fs, duration=float(u.t[-1] - u.t[0]),
                                           channels=F.sim_channels(u), max_wall_s=600.0, **u.sim_kw)
        except Exception as e:  # noqa: BLE001 - one invalid member must not lose the population
            failures.append(f"{u.key}: {type(e).__name__}: {e}")
            continue
        n_sims += len(members)
        for m, j in enumerate(members):
            if bad[j] or status[m] != 0:
                continue
            s = F.sim_signals(u, ch, m)
            rows[j] = F.sim_features(u, s, fcfg)
            sig[j] = s if keep else None
    return rows, sig, n_sims, failures


def _worker_init() -> None:
    """Record workers: one numba thread each (the pool supplies the parallelism)."""
    import numba

    numba.set_num_threads(1)


def record_pool(workers: int | None):
    """A process pool for ``Problem.executor`` (None for one worker)."""
    import os
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    workers = (os.cpu_count() or 1) if workers is None else int(workers)
    if workers <= 1:
        return None
    return ProcessPoolExecutor(workers, mp_context=get_context("spawn"), initializer=_worker_init)


def select_params(J: np.ndarray, r: np.ndarray, k: int) -> list:
    """Up to ``k`` columns of ``J`` (whitened sensitivities [features, params])
    that explain the residual ``r`` best, chosen by orthogonal matching
    pursuit (Pati et al., Asilomar 1993): each step takes the column whose
    part orthogonal to the columns already taken removes the most of what
    is left of ``r``. Unlike ranking the columns one by one, three
    parameters of one valve that move the same features count once, so the
    refit reaches the other disagreeing records' parameters. Columns with
    no independent part (< 1e-6 of their norm) or no gain are never taken."""
    Q = np.asarray(J, float).copy()
    res = np.asarray(r, float).copy()
    norms = np.sqrt(np.sum(Q * Q, axis=0))
    out: list = []
    for _ in range(min(k, Q.shape[1])):
        nq = np.sqrt(np.sum(Q * Q, axis=0))
        ok = nq > 1e-6 * np.maximum(norms, 1e-300)
        gain = np.where(ok, (Q.T @ res) ** 2 / np.where(ok, nq * nq, 1.0), 0.0)
        gain[out] = 0.0
        j = int(np.argmax(gain))
        if gain[j] <= 0.0:
            break
        out.append(j)
        q = Q[:, j] / nq[j]
        res = res - q * (q @ res)
        Q = Q - np.outer(q, q @ Q)
    return out


# report wording only: a held-out chi^2 within 10 % of its feature count is "at or near noise level",
# where a closed fraction of the (tiny) excess reads as an absurd percentage (-1666 %)
NEAR_NOISE = 1.1


def chi(z: np.ndarray, mask: np.ndarray) -> float:
    """Sum of squared noise-scaled residuals (inf when a member failed)."""
    v = z[..., mask]
    return float(np.sum(v * v)) if np.all(np.isfinite(v)) else math.inf


def mean_z2(z: np.ndarray, mask: np.ndarray) -> float:
    n = int(np.sum(mask))
    return chi(z, mask) / max(n, 1)


def worst_record(problem: "Problem", z: np.ndarray, mask: np.ndarray, alpha: float) -> tuple[float, str]:
    """Per-record chi-square test of the whitened residual: the largest ratio
    (sum of z^2 over a record's features) / (its chi-square quantile at
    1 - alpha / records, Bonferroni) and that record. A ratio above 1 is a
    disagreement localised in one record (the slowest curving run, say) that
    the mean over every feature would dilute; under the noise model the
    chance that any agreeing record exceeds it is <= alpha."""
    from scipy.stats import chi2 as chi2_dist

    blocks, k = [], 0
    for u in problem.units:
        n = len(u.labels)
        m = mask[k:k + n]
        if m.any():
            blocks.append((u.key, z[k:k + n][m]))
        k += n
    worst, key = 0.0, ""
    q = 1.0 - alpha / max(len(blocks), 1)
    quant = {n: float(chi2_dist.ppf(q, n)) for n in {len(v) for _, v in blocks}}
    for name, v in blocks:
        val = float(np.sum(v * v)) / quant[len(v)] if np.all(np.isfinite(v)) else math.inf
        if val > worst:
            worst, key = val, name
    return worst, key


# ------------------------------------------------------------------ fitting
@dataclass
class Fit:
    name: str
    params: list
    values: dict
    design: Design
    S: Row                   # simulated features at the fit
    overrides: dict          # all overrides applied to the base design
    J: dict = field(default_factory=dict)   # key -> d z / d u at the fit (Broyden-updated)


def gauss_newton(problem: Problem, base: Design, fixed: dict, params: list, mask: np.ndarray, iterations: int,
                 step: float, label: str, S0: Row | None = None, J0: dict | None = None,
                 prior: dict | None = None) -> Fit:
    """Bounded Levenberg-Marquardt on the whitened features of ``mask``
    (scipy ``lsq_linear`` per step). Jacobian columns come from ``J0`` (key
    -> d z / d u, e.g. the sensitivity batch) or one finite-difference batch
    at the start; later steps update them (Broyden), so an iteration costs
    one simulation per record. ``prior`` (key -> (value, sigma in u)) keeps
    parameters near a value (Tikhonov rows: a refit of many parameters on few
    records must not trade miscalibration for overfitting)."""
    from scipy.optimize import lsq_linear

    def design_at(u):
        ov = {**fixed, **{p.key: p.to_v(x) for p, x in zip(params, u)}}
        return base.with_overrides(ov), ov

    u = np.array([p.to_u(p.start) for p in params])
    try:
        d0, _ = design_at(u)
    except DesignError:
        u = np.clip(u, 0.05, 0.95)
        d0, _ = design_at(u)
    J0 = J0 or {}
    fd = [i for i, p in enumerate(params) if p.key not in J0]
    pts, hs = ([u] if S0 is None else []), []
    for i in fd:
        v = u.copy()
        h = step if u[i] + step <= 1.0 else -step
        v[i] = u[i] + h
        try:
            design_at(v)
        except DesignError:  # outside the valid set (F_c > F_s, say): step the other way (sensitivity)
            h = -h
            v[i] = u[i] + h
        hs.append(h)
        pts.append(v)
    rows = _rows(problem, design_at, d0, pts, f"{label} start")
    S_cur = S0 if S0 is not None else rows.pop(0)
    z_cur = problem.z(S_cur)
    nf = len(z_cur)
    J = np.zeros((nf, len(params)))
    for i, p in enumerate(params):
        if p.key in J0:
            J[:, i] = J0[p.key]
    for k, i in enumerate(fd):
        col = (problem.z(rows[k]) - z_cur) / hs[k]
        J[:, i] = np.where(np.isfinite(col), col, 0.0)
    prior = prior or {}
    pc = np.array([params[i].to_u(prior[p.key][0]) if p.key in prior else 0.0 for i, p in enumerate(params)])
    pw = np.array([1.0 / prior[p.key][1] if p.key in prior else 0.0 for p in params])

    def obj(z, u):
        return chi(z, mask) + float(np.sum((pw * (u - pc)) ** 2))

    best = (obj(z_cur, u), u.copy(), S_cur, z_cur)
    lam = 1e-2
    for it in range(iterations):
        if not params or not np.isfinite(best[0]):
            break
        u, S_cur, z_cur = best[1].copy(), best[2], best[3]
        A = np.vstack([J[mask], np.diag(pw), math.sqrt(lam) * np.eye(len(params))])
        bb = np.concatenate([-z_cur[mask], -pw * (u - pc), np.zeros(len(params))])
        du = lsq_linear(A, bb, bounds=(-u - 1e-12, 1.0 - u + 1e-12)).x
        if np.max(np.abs(du)) < 1e-4:
            break
        u_new = np.clip(u + du, 0.0, 1.0)
        du = u_new - u
        S_new = _rows(problem, design_at, d0, [u_new], f"{label} it {it + 1}")[0]
        z_new = problem.z(S_new)
        if np.all(np.isfinite(z_new)):  # Broyden update of the Jacobian along the step
            J += np.outer(z_new - z_cur - J @ du, du) / float(du @ du)
        c_new = obj(z_new, u_new)
        if c_new < best[0]:
            best = (c_new, u_new, S_new, z_new)
            lam = max(lam / 3, 1e-4)
        else:
            lam *= 10
    c, u, S_best, _ = best
    d, ov = design_at(u)
    f = Fit(label, params, {p.key: p.to_v(x) for p, x in zip(params, u)}, d, S_best, ov)
    f.J = {p.key: J[:, i] for i, p in enumerate(params)}
    return f


def _rows(problem: Problem, design_at, d0, pts, label) -> list:
    designs, ok = [], []
    for v in pts:
        try:
            designs.append(design_at(v)[0])
            ok.append(True)
        except DesignError:
            designs.append(d0)
            ok.append(False)
    if not designs:
        return []
    S = problem.simulate(designs, label=label)
    return [r if o else _nan_row(r) for r, o in zip(S, ok)]


def sensitivity(problem: Problem, base: Design, params: list, step: float, label: str):
    """Simulated features of the base and of each parameter stepped (one batch)."""
    designs, ok = [base], [True]
    hs = []
    for p in params:
        u = p.to_u(p.start)
        h = step if u + step <= 1.0 else -step
        try:
            designs.append(base.with_overrides({p.key: p.to_v(u + h)}))
            ok.append(True)
        except DesignError:
            # the step left the design's valid set (e.g. rod friction F_c above F_s, eq. 4.41 needs
            # F_c <= F_s): step the other way rather than lose the parameter's sensitivity
            h = -h
            try:
                designs.append(base.with_overrides({p.key: p.to_v(u + h)}))
                ok.append(True)
            except DesignError:
                designs.append(base)
                ok.append(False)
        hs.append(h)
    S = problem.simulate(designs, label=label)
    return [r if o else _nan_row(r) for r, o in zip(S, ok)], np.array(hs)


def _nan_row(r: Row) -> Row:
    return Row([np.full_like(p, np.nan) for p in r.pcs])


def resolvability(problem: Problem, base: Design, S_base: Row, cands: list, J: np.ndarray, prior_sigma: float,
                  alpha: float, separating: dict) -> list[dict]:
    """What the records present can resolve: each candidate switched on at
    its typical magnitude on ``base``, its whitened signature (bench gain /
    offset allowances already in the whitening) minus what the calibration
    pool absorbs (columns ``J`` = d z / d u, prior width ``prior_sigma`` in
    u as in the refit), as chi^2 in its most affected record over that
    record's gate quantile (``worst_record``). ratio >= 1: the typical
    magnitude alone exceeds the gate; otherwise about 1 / sqrt(ratio) x the
    typical magnitude would be needed (signature linear in the magnitude).
    A `none` verdict says nothing about an effect with ratio << 1."""
    if not cands:
        return []
    # a candidate that cannot be switched on gets a NaN row (_rows): ratio None below
    S = _rows(problem, lambda c: (base.with_overrides(c.overrides()),), base, cands, "resolvability")
    zb = problem.z(S_base)
    allm = problem.mask(None)
    n = J.shape[1]
    A = np.vstack([J, np.eye(n) / prior_sigma]) if n else None
    out = []
    for c, row in zip(cands, S):
        zs = problem.z(row)
        entry = {"effect": c.name, "ratio": None, "record": "", "resolvable": None,
                 "min_factor": None, "separating_test": separating.get(c.name, separating.get("default", ""))}
        if np.all(np.isfinite(zs)) and np.all(np.isfinite(zb)):
            s = zb - zs   # the residual the effect would leave if the model lacked it
            if n:
                a = np.linalg.lstsq(A, np.concatenate([s, np.zeros(n)]), rcond=None)[0]
                s = s - J @ a
            ratio, rec = worst_record(problem, s, allm, alpha)
            entry.update(ratio=round(ratio, 4), record=rec, resolvable=bool(ratio >= 1.0),
                         min_factor=round(1.0 / math.sqrt(ratio), 3) if ratio > 0 else None)
        out.append(entry)
    return out


# ------------------------------------------------------------------ the workflow
def assign_folds(units: list) -> None:
    """Training / held-out records: alternate over the damper / module
    records in test order, so held-out data are other velocities / currents /
    cases / tests than the fitted ones. Within a multi-run record (curving:
    velocities x currents) the runs alternate over velocity and the pattern
    flips from one current to the next (a checkerboard), so every current
    and, with two or more runs per current, low and higher velocities are in
    both sets. Flow-bench records (the valves alone) are always training
    data: they pin the valve parameters in every refit. A single record is
    both (said in the report)."""
    i = 0
    groups: dict = {}
    for u in units:
        if u.configuration == "valve":
            u.fold = "train"
            continue
        groups.setdefault((u.test, u.case), []).append(u)
    for grp in groups.values():
        currents = sorted({round(u.current, 3) for u in grp})
        by_cur = {c: sorted((u for u in grp if round(u.current, 3) == c), key=lambda u: u.frequency or 0.0)
                  for c in currents}
        for k, c in enumerate(currents):
            for j, u in enumerate(by_cur[c]):
                u.fold = "train" if (i + j + k) % 2 == 0 else "heldout"
        i += len(grp)
    if len(units) == 1:
        units[0].fold = "train"


def _gap(z, mask) -> float:
    """RMS noise-scaled residual of the features in ``mask``."""
    return math.sqrt(mean_z2(z, mask)) if np.isfinite(mean_z2(z, mask)) else math.inf


def _where(problem: Problem, z: np.ndarray, dcfg: dict) -> list:
    """Bins / bands whose |residual| / noise exceeds ``where_z``: test, case
    (the file's case), phase_or_band (the run, when the file holds several,
    the channel and the phase bin or band), excess (|residual| / noise)."""
    n_runs: dict = {}
    for u in problem.units:
        n_runs[(u.test, u.case)] = n_runs.get((u.test, u.case), 0) + 1
    out = []
    for (test, case, run, ch, ph), v in zip(problem.labels, z):
        if np.isfinite(v) and abs(v) >= float(dcfg["where_z"]):
            where = f"{ch}: {ph}" if n_runs[(test, case)] == 1 else f"{run} {ch}: {ph}"
            out.append({"test": test, "case": case, "phase_or_band": where, "excess": round(float(abs(v)), 2)})
    out.sort(key=lambda r: -r["excess"])
    return out[: int(dcfg["where_max"])]


def run(design: Design, problem: Problem, cfg: dict, profile: str, seed: int) -> dict:
    """The whole workflow on prepared units. Returns the verdict document
    plus everything the report needs (designs, features, fits)."""
    prof = cfg["profiles"][profile]
    dcfg = cfg["decision"]
    step = float(dcfg["step"])
    units = problem.units
    if len(units) > 1:
        assign_folds(units)
    train, held = problem.mask("train"), problem.mask("heldout")
    in_sample = not held.any()  # one record, or flow-bench records only: nothing to hold out
    if in_sample:
        held = train
    allm = problem.mask(None)
    M = problem.measured()
    log: list[str] = []

    # 1. Find ----------------------------------------------------------------
    pool = calibration_params(design, cfg)
    S_sens, hs = sensitivity(problem, design, pool, step, "find + sensitivities")
    S0 = S_sens[0]
    if not S0.ok:
        raise RuntimeError("the design under test cannot be simulated on the measured records")
    problem.set_noise(S0)
    z0 = problem.z(S0)
    if not np.all(np.isfinite(z0)):
        raise RuntimeError("the design under test cannot be simulated on the measured records")
    mz0 = mean_z2(z0, allm)
    alpha = float(dcfg.get("record_alpha", 0.0))
    wz0, wkey0 = worst_record(problem, z0, allm, alpha) if alpha > 0 else (0.0, "")
    where = _where(problem, problem.zdiag(S0), dcfg)
    res = {"z0": z0, "S0": S0, "where": where, "log": log, "fits": {}, "candidates": [], "cal": None,
           "pool": pool, "train": train, "heldout": held, "in_sample": in_sample}
    log.append(f"design under test: mean squared noise-scaled residual {mz0:.2f} over {int(allm.sum())} features "
               f"({problem.n_eff()} cycles / segments); threshold {dcfg['disagree_mean_z2']}; worst record "
               f"{wkey0}: chi^2 / its {100 * (1 - alpha):g} % quantile (Bonferroni over records) {wz0:.2f}")
    gap_before = _gap(z0, held)
    Jc = np.zeros((len(M), len(pool)))
    for i in range(len(pool)):
        col = (problem.z(S_sens[i + 1]) - z0) / hs[i]
        Jc[:, i] = np.where(np.isfinite(col), col, 0.0)

    def resolved(base, S_base):
        """Before a `none`: which candidates these records could have seen (report)."""
        if not dcfg.get("resolvability", True) or alpha <= 0:
            return
        rs = resolvability(problem, base, S_base, catalogue(design, cfg), Jc, float(dcfg.get("prior_sigma", 0.1)),
                           alpha, cfg.get("separating_tests", {}) or {})
        res["resolvability"] = rs
        weak = [r for r in rs if r["resolvable"] is False]
        if weak:
            log.append("not resolvable on these records at the typical magnitude (signature beyond the calibration "
                       "pool and bench allowances / the record gate): "
                       + ", ".join(f"{r['effect']} {r['ratio']:.2f} ("
                                   + (f"needs ~{r['min_factor']:.1f}x" if r["min_factor"] is not None
                                      else "no signature at all on these records")
                                   + f"; {r['separating_test']})" for r in weak))

    def finish(verdict, effects, group, final_design, S_final, overrides):
        zf = problem.z(S_final)
        gb, ga = gap_before, _gap(zf, held)
        nb, na = chi(z0, held), chi(zf, held)
        nh = int(held.sum())
        closed = 0.0 if nb <= nh else float(min(1.0, (nb - na) / (nb - nh)))
        res.update(verdict=verdict, effects=effects, group=group, design=final_design, S_final=S_final,
                   z_final=zf, overrides=overrides,
                   gap={"before": round(gb, 4), "after": round(ga, 4), "closed_fraction": round(closed, 4)})
        return res

    if mz0 <= float(dcfg["disagree_mean_z2"]) and wz0 <= 1.0:
        log.append("no disagreement beyond noise and bench error: verdict none")
        resolved(design, S0)
        return finish("none", [], [], design, S0, {})

    # 2. Separate miscalibration ------------------------------------------------
    order = select_params(Jc[train], z0[train], int(prof["calibration"]["max_params"]))
    sel = [pool[i] for i in order]
    ps = float(dcfg.get("prior_sigma", 0.1))
    prior = {p.key: (p.start, ps) for p in sel}  # the design's own values
    log.append("calibration refit of " + ", ".join(p.key for p in sel) + " (orthogonal matching pursuit on the residual)")
    cal = gauss_newton(problem, design, {}, sel, train, int(prof["calibration"]["iterations"]), step, "calibration refit",
                       S0=S0, J0={pool[i].key: Jc[:, i] for i in order}, prior=prior)
    z_cal = problem.z(cal.S)
    res["cal"] = cal
    mz_cal_h, mz_cal_all = mean_z2(z_cal, held), mean_z2(z_cal, allm)
    wz_cal, wkey_cal = worst_record(problem, z_cal, allm, alpha) if alpha > 0 else (0.0, "")
    log.append(f"after the calibration refit: mean z^2 held-out {mz_cal_h:.2f}, all {mz_cal_all:.2f}; worst record "
               f"{wkey_cal} {wz_cal:.2f} (chi^2 / quantile)")
    if mz_cal_h <= float(dcfg["ok_mean_z2"]) and mz_cal_all <= float(dcfg["ok_mean_z2"]) and wz_cal <= 1.0:
        log.append("the calibration refit explains the data: calibration only, verdict none")
        resolved(cal.design, cal.S)
        return finish("none", [], [], cal.design, cal.S, cal.values)

    # 3. Name -------------------------------------------------------------------
    if in_sample:
        log.append("no held-out record (a single record, or flow-bench records only): an effect is not named on "
                   "in-sample fits, where any extra parameter improves the fit; verdict unexplained. Add records of "
                   "other tests / currents / velocities")
        return finish("unexplained", [], [], design, S0, {})
    cands = catalogue(design, cfg)
    if not cands:
        log.append("no candidate effect (every library effect is on in the design): verdict unexplained")
        return finish("unexplained", [], [], design, S0, {})
    sig_designs, okc = [], []
    for c in cands:
        try:
            sig_designs.append(cal.design.with_overrides(c.overrides()))
            okc.append(True)
        except DesignError as e:
            log.append(f"candidate {c.name}: cannot be switched on ({e}); skipped")
            sig_designs.append(cal.design)
            okc.append(False)
    S_sig = [r if o else _nan_row(r) for r, o in zip(problem.simulate(sig_designs, label="signatures"), okc)]
    Jsel = Jc[:, order] if order else np.zeros((len(M), 0))
    Q = np.linalg.qr(Jsel[train])[0] if Jsel.shape[1] else np.zeros((int(train.sum()), 0))
    rz = z_cal[train] - Q @ (Q.T @ z_cal[train])
    ranking = []
    for c, ok, s_row in zip(cands, okc, S_sig):
        zs = problem.z(s_row)
        if not ok or not np.all(np.isfinite(zs)):
            ranking.append((c, 0.0, None))
            continue
        s = (zs - z_cal)[train]
        s = s - Q @ (Q.T @ s)
        ss, sr = float(s @ s), float(s @ rz)
        # z + a s: the effect explains the residual when a > 0 reduces it
        expl = (sr * sr / ss) / max(float(rz @ rz), 1e-300) if ss > 0 and sr < 0 else 0.0
        ranking.append((c, expl, zs))
    ranking.sort(key=lambda x: -x[1])
    log.append("signature match (share of the training residual a candidate's signature explains): "
               + ", ".join(f"{c.name} {e:.2f}" for c, e, _ in ranking))
    top = [c for c, e, _ in ranking if e > 0][: int(prof["candidates"]["refit_top"])]
    fits: dict[str, Fit] = {}
    cal_start = [FitParam(p.key, p.lo, p.hi, cal.values[p.key]) for p in sel]
    its = int(prof["candidates"]["iterations"])
    n_tr = max(problem.n_eff("train"), 2)
    for c in top:
        # (a) the effect alone on the design, (b) the effect with the calibration parameters (prior
        # at the design's values); the one with the lower penalised training chi^2 is kept
        fa = gauss_newton(problem, design, c.overrides(), c.params, train, its, step, f"refit {c.name}")
        fb = gauss_newton(problem, design, c.overrides(), c.params + cal_start, train, its, step,
                          f"refit {c.name} + calibration", J0={**cal.J, **fa.J}, prior=prior)
        ca = chi(problem.z(fa.S), train) + len(c.params) * math.log(n_tr)
        cb = chi(problem.z(fb.S), train) + (len(c.params) + len(cal_start)) * math.log(n_tr)
        fits[c.name] = fa if ca <= cb else fb
    # pairs by forward selection: the lead is the best single fit on training data (penalised chi^2);
    # its partners are ranked like the first round, on what the lead fit leaves: each other candidate
    # switched on (typical magnitude) on top of the lead's fitted design, the share of the lead fit's
    # training residual its signature explains once the calibration and the lead's own directions are
    # projected out (an effect hidden under a dominant one shows only after the dominant one is fitted)
    def train_chi(n):
        return chi(problem.z(fits[n].S), train)

    n_pairs = int(prof["candidates"].get("pairs", 0))
    partners: list = []
    lead = min(top, key=lambda c: train_chi(c.name) + len(c.params) * math.log(n_tr)) if top else None
    if n_pairs > 0 and lead is not None:
        # forward selection stops when the lead fit leaves no disagreement by the same gates as `none`
        z_l = problem.z(fits[lead.name].S)
        wz_l, wk_l = worst_record(problem, z_l, allm, alpha) if alpha > 0 else (0.0, "")
        if (mean_z2(z_l, held) <= float(dcfg["ok_mean_z2"]) and mean_z2(z_l, allm) <= float(dcfg["ok_mean_z2"])
                and wz_l <= 1.0):
            log.append(f"the lead fit ({lead.name}) leaves no disagreement (mean z^2 held-out {mean_z2(z_l, held):.2f}, "
                       f"all {mean_z2(z_l, allm):.2f}; worst record {wk_l} {wz_l:.2f}): no partner is sought")
            n_pairs = 0
    if n_pairs > 0 and lead is not None:
        lf = fits[lead.name]
        others, designs2 = [], []
        for c in cands:
            if c.name == lead.name:
                continue
            try:
                designs2.append(lf.design.with_overrides(c.overrides()))
                others.append(c)
            except DesignError:
                continue
        S2 = problem.simulate(designs2, label=f"partner signatures on {lead.name}") if designs2 else []
        z_lead = problem.z(lf.S)
        cols = [Jsel[:, i] for i in range(Jsel.shape[1])] + [lf.J[p.key] for p in lead.params if p.key in lf.J]
        Q2 = np.linalg.qr(np.column_stack(cols)[train])[0] if cols else np.zeros((int(train.sum()), 0))
        r2 = z_lead[train] - Q2 @ (Q2.T @ z_lead[train])
        share2 = []
        for c, row in zip(others, S2):
            zs = problem.z(row)
            if not np.all(np.isfinite(zs)):
                continue
            s2 = (zs - z_lead)[train]
            s2 = s2 - Q2 @ (Q2.T @ s2)
            ss, sr = float(s2 @ s2), float(s2 @ r2)
            if ss > 0 and sr < 0:
                share2.append(((sr * sr / ss) / max(float(r2 @ r2), 1e-300), c))
        share2.sort(key=lambda x: -x[0])
        log.append(f"partner signatures on the lead fit ({lead.name}): "
                   + (", ".join(f"{c.name} {e:.2f}" for e, c in share2) or "none explains its residual"))
        partners = [c for _, c in share2[:n_pairs]]

    # the nested reference of every pair: the lead refitted together with the calibration parameters
    # re-selected on what the lead fit leaves (the first selection was made on the residual of the
    # design under test, where the lead's own signature dominated). A partner is named only when it
    # gains on held-out data over this reference: a small miscalibration the first selection missed
    # (e.g. a shim stack's friction) is the calibration pool's to absorb, not a second effect's.
    recal, nested_label = None, ""
    if partners:
        lf = fits[lead.name]
        z_l = problem.z(lf.S)
        order_l = select_params(Jc[train], z_l[train], int(prof["calibration"]["max_params"]))
        lead_keys = {p.key for p in lead.params}
        # the lead fit's own calibration parameters (if it had any) and the re-selected ones
        sel_l = list({p.key: p for p in [q for q in pool if q.key in lf.values and q.key not in lead_keys]
                      + [pool[i] for i in order_l]}.values())
        lv = lf.values
        rec_params = [FitParam(p.key, p.lo, p.hi, lv.get(p.key, p.start)) for p in lead.params + sel_l]
        J0r = {**{p.key: Jc[:, pool.index(p)] for p in sel_l}, **lf.J}
        prior_l = {p.key: (p.start, ps) for p in sel_l}  # around the design's own values, as the first refit
        # the start is the lead fit itself (every parameter it fitted is in rec_params, the others at the
        # design's values as in the lead fit): no new simulation for it
        recal = gauss_newton(problem, design, lead.overrides(), rec_params, train, its, step,
                             f"refit {lead.name} + recalibration", S0=lf.S, J0=J0r, prior=prior_l)
        nested_label = f"{lead.name} refitted with the re-selected calibration parameters"
        z_r = problem.z(recal.S)
        wz_r, wk_r = worst_record(problem, z_r, allm, alpha) if alpha > 0 else (0.0, "")
        log.append(f"nested reference of the pairs: {lead.name} refitted with "
                   + ", ".join(p.key for p in sel_l) + " (re-selected on the lead fit's residual): mean z^2 "
                   f"held-out {mean_z2(z_r, held):.2f}, all {mean_z2(z_r, allm):.2f}; worst record {wk_r} {wz_r:.2f}")
        if chi(z_r, held) > chi(problem.z(lf.S), held):
            # the further calibration traded held-out agreement for training agreement (parameters that
            # compensate each other on the fitted records): the lead fit itself is the better one-effect
            # description, and the pairs start from it and must beat it
            log.append(f"the recalibrated {lead.name} describes the held-out data worse (mean z^2 "
                       f"{mean_z2(z_r, held):.2f}) than the {lead.name} fit ({mean_z2(problem.z(lf.S), held):.2f}): "
                       "the pairs start from, and are tested against, the lead fit")
            recal, prior_l = lf, prior
            nested_label = f"the {lead.name} fit"

    # partners are tried down their ranking until one is eligible (at most `pairs`): the partner test's
    # alpha is shared among the partners that may be tried (Bonferroni), so trying more does not make a
    # chance partner likelier to pass
    from scipy.stats import chi2 as chi2_dist

    partner_alpha = float(dcfg.get("partner_alpha", 0.01)) / max(len(partners), 1)
    pair_test: dict[str, dict] = {}

    def pen_of(c):
        return max(len(c.params), len(c.effects)) * math.log(n_tr)

    for b in partners:
        pc = Candidate(f"{lead.name}+{b.name}", lead.effects + b.effects, lead.params + b.params,
                       {**lead.typical, **b.typical})
        # the partner joins the nested reference (its values, its Jacobian) at its typical magnitude,
        # with the same re-selected calibration parameters and prior
        rv = recal.values
        start = [FitParam(p.key, p.lo, p.hi, rv.get(p.key, p.start)) for p in pc.params]
        cs = [FitParam(p.key, p.lo, p.hi, rv[p.key]) for p in recal.params if p.key not in {q.key for q in pc.params}]
        fits[pc.name] = gauss_newton(problem, design, pc.overrides(), start + cs, train, its, step,
                                     f"refit {pc.name}", J0=dict(recal.J), prior=prior_l)
        top.append(pc)
        # (a) nested: the partner's own parameters must earn their penalty over the lead + recalibration,
        # and their held-out chi^2 drop must be significant as a likelihood-ratio test of nested models
        # (chi^2 with k_b degrees of freedom at the partner alpha): with few cycles (a record of
        # single-cycle runs) k ln(cycles) alone is weaker than the chance drop of k_b free parameters.
        # (b) the pair must describe the held-out data better, after its penalty, than each of its
        # effects refitted alone (absolute held-out chi^2 + penalty: the lead's fit and the pair's
        # refit start from different calibrations, so their gains over their own baselines do not compare)
        k_b = max(len(b.params), 1)
        pen_b = max(k_b * math.log(n_tr), float(chi2_dist.ppf(1.0 - partner_alpha, k_b)))
        ch_pair = chi(problem.z(fits[pc.name].S), held)
        nested = chi(problem.z(recal.S), held) - ch_pair - pen_b
        alone = {m: chi(problem.z(fits[m].S), held) + pen_of(next(c for c in top if c.name == m))
                 for m in (lead.name, b.name) if m in fits}
        pair_test[pc.name] = {"nested_gain": nested, "nested_penalty": pen_b, "abs": ch_pair + pen_of(pc),
                              "alone_abs": alone}
        ok = nested > 0 and ch_pair + pen_of(pc) < min(alone.values())
        log.append(f"pair {pc.name}: the partner gains {nested:.1f} in held-out chi2 after its penalty {pen_b:.1f} "
                   f"over {nested_label}; held-out chi2 + penalty "
                   f"{ch_pair + pen_of(pc):.1f} (alone: " + ", ".join(f"{m} {v:.1f}" for m, v in alone.items()) + ")"
                   + ("" if ok else ": not eligible"))
        if ok and dcfg.get("partner_resolvable", True) and alpha > 0:
            # (c) relevance, beside (a)'s significance: the partner at its fitted values must move some
            # record past its gate (its signature: the pair fit with the partner switched off, minus the
            # pair fit; chi^2 over the record's gate quantile, as `worst_record`). A partner fitted at a
            # small fraction of its typical magnitude can pass (a) by absorbing model error spread thinly
            # over many records (rod_friction_asymmetric at 0.15x typical on the shipped sample: 0.14 x
            # the gate); a real partner moves its record well past it (a 60 um leakage beside a valve
            # lag: 2.6 x). The signature is taken at the pair's own calibration, not less what the pool
            # could absorb: (a) already measured what the recalibrated lead absorbs, and the projection
            # on the whole pool (a linear, weakly-penalised worst case) rejected that leakage (0.66 x).
            # The lead is held to the same test inside the pair (decision.lead_resolvable): a lead that
            # won the first round as a chance match (rod_friction_asymmetric beside a hidden seal, seed
            # 101) ends up carrying little once the true effect joins it as partner
            z_p = problem.z(fits[pc.name].S)
            parts = [("partner", b)] + ([("lead", lead)] if dcfg.get("lead_resolvable", True) else [])
            offs_p = problem.simulate([fits[pc.name].design.with_overrides({f"effects.{e}": False for e in m.effects})
                                       for _, m in parts], f"{pc.name}: each effect off")
            for (role, m), off_m in zip(parts, offs_p):
                sig = problem.z(off_m) - z_p
                ratio, rec = worst_record(problem, sig, allm, alpha) if np.all(np.isfinite(sig)) else (0.0, "")
                pair_test[pc.name][f"{role}_ratio"] = ratio
                log.append(f"pair {pc.name}: the {role} ({m.name}) at its fitted values moves its most affected "
                           f"record {rec} by {ratio:.2f} x the record gate" + ("" if ratio >= 1.0 else
                                                                               ": below the gate, not eligible"))
            ok = _pair_eligible(pair_test[pc.name])
        if ok:
            break
    res["fits"] = fits

    # 4. Decide on held-out data -----------------------------------------------------
    n_eff = max(problem.n_eff("train"), 2)
    # reference: the better of the design under test and its calibration refit on held-out data
    ref = cal if chi(z_cal, held) <= chi(z0, held) else Fit("design under test", [], {}, design, S0, {})
    chi_cal_h = chi(problem.z(ref.S), held)
    nh = int(held.sum())
    # each fit with its effect(s) switched off, the refitted calibration values kept: the nested model
    # at the same calibration. A candidate refitted together with calibration parameters is credited
    # only with what its effect adds there, never with what the further refit of the calibration
    # parameters reached alone (a null effect, oil heating on seconds-long records, once took the
    # credit for a better calibration and was named on a control)
    offs = problem.simulate([fits[c.name].design.with_overrides({f"effects.{e}": False for e in c.effects})
                             for c in top], "effects off at the fits")
    off_of = {c.name: row for c, row in zip(top, offs)}
    stats = {}
    for c in top:
        f = fits[c.name]
        zf = problem.z(f.S)
        k = max(len(c.params), len(c.effects))
        pen = k * math.log(n_eff)
        ch_ = chi(zf, held)
        chi_off = chi(problem.z(off_of[c.name]), held)
        closed = (chi_cal_h - ch_) / max(chi_cal_h - nh, 1e-9)
        stats[c.name] = {"gain": min(chi_cal_h, chi_off) - ch_ - pen, "abs_score": ch_ + pen, "closed": closed,
                         "penalty": pen, "k": k,
                         "cand": c, "own": chi_off - ch_}
    # a pair is eligible when its partner passes the nested test (a) and the relevance test (c) and the
    # pair beats each of its effects alone (b, absolute held-out chi^2 + penalty); like any candidate it
    # must then gain on held-out data over its own calibration and close half the gap. Neither effect
    # needs to gain alone: two effects can each make the held-out fit worse alone and better together
    # (a leakage that softens the low-velocity force and a seal that stiffens it at 14 bar)
    for n in list(stats):
        if "+" in n:
            stats[n].update(pair_test[n])
            if not _pair_eligible(pair_test[n]):
                stats[n]["eligible"] = False
                log.append(f"{n}: not eligible (the partner does not earn its penalty over {nested_label}, the pair "
                           "does not beat one of its effects alone, or the partner's or the lead's fitted signature is "
                           "below the record gate)")
    rng = np.random.default_rng(seed)
    B = int(prof["bootstrap"])
    names = [n for n in stats if stats[n].get("eligible", True)]
    wins = dict.fromkeys(names, 0)
    for _ in range(B):
        boot = [rng.integers(0, u.n_cycles, u.n_cycles) for u in units]
        cb = chi(problem.z(ref.S, boot), held)
        fit_b = {n: chi(problem.z(fits[n].S, boot), held) for n in names}
        g = {n: min(cb, chi(problem.z(off_of[n], boot), held)) - fit_b[n] - stats[n]["penalty"] for n in names}
        bn = _pick(g, {n: fit_b[n] + stats[n]["penalty"] for n in names})
        if bn is not None:
            wins[bn] += 1
    for n in stats:
        stats[n]["share"] = wins.get(n, 0) / max(B, 1)
    res["stats"] = stats
    for n, st in stats.items():
        log.append(f"{n}: held-out chi2 gain {st['gain']:.1f} after a penalty of {st['penalty']:.1f} "
                   f"({st['k']} parameter(s) x ln {n_eff} cycles; the effect's own held-out chi2 drop at the fitted calibration values "
                   f"{st['own']:.1f}), "
                   + (f"closes {100 * min(st['closed'], 1.0):.0f} % of the held-out gap left by the "
                      f"{'calibration refit' if ref is cal else 'design under test'}" if chi_cal_h > NEAR_NOISE * nh else
                      f"{'lowers' if st['closed'] > 0 else 'raises'} the held-out chi2 (the "
                      f"{'calibration refit' if ref is cal else 'design under test'} left it at or near noise level: "
                      f"{chi_cal_h:.0f} for {nh} features; a record's gate disagreed)")
                   + f", wins {100 * st['share']:.0f} % of {B} cycle bootstraps"
                   + (f"; the partner gains {st['nested_gain']:.1f} after its penalty {st['nested_penalty']:.1f} over "
                      f"{nested_label}" if "nested_gain" in st else ""))
    viable = [n for n in names if stats[n]["gain"] > 0 and stats[n]["closed"] >= float(dcfg["min_closed"])]
    cand_rows = []
    for c, e, _ in ranking:
        f = fits.get(c.name)
        cand_rows.append({"effect": c.name, "score": round(float(e), 4), "heldout_gap_before": round(gap_before, 4),
                          "heldout_gap_after": None if f is None else round(_gap(problem.z(f.S), held), 4),
                          "parameters": {k: float(v) for k, v in (f.values if f else c.typical).items()
                                         if not any(k == p.key for p in sel)}})
    for c in top:
        if "+" in c.name:
            f = fits[c.name]
            cand_rows.append({"effect": c.name, "score": round(float(stats[c.name]["share"]), 4),
                              "heldout_gap_before": round(gap_before, 4),
                              "heldout_gap_after": round(_gap(problem.z(f.S), held), 4),
                              "parameters": {k: float(v) for k, v in f.values.items()
                                             if not any(k == p.key for p in sel)}})
    res["candidates"] = cand_rows
    if not viable:
        log.append(f"no candidate closes >= {100 * float(dcfg['min_closed']):.0f} % of the held-out gap with a "
                   "positive penalised gain: verdict unexplained")
        return finish("unexplained", [], [], design, S0, {})
    best = _pick({n: stats[n]["gain"] for n in viable},
                 {n: stats[n]["abs_score"] for n in viable})
    order_v = sorted(viable, key=lambda n: -stats[n]["gain"])
    group = [n for n in order_v if stats[n]["share"] >= float(dcfg["group_share"]) or n == best]
    f = fits[best]
    effs = stats[best]["cand"].effects
    if stats[best]["share"] >= float(dcfg["stable"]) or (len(group) == 1 and stats[best]["share"] >= 0.5):
        log.append(f"named: {' + '.join(effs)}")
        return finish("named", list(effs), [], f.design, f.S, f.values)
    if len(group) >= 2:
        flat = list(dict.fromkeys(e for n in group for e in stats[n]["cand"].effects))
        sep = cfg.get("separating_tests", {}) or {}
        tests = sorted({sep.get(e, sep.get("default", "curving")) for e in flat})
        res["separating_tests"] = tests
        log.append(f"ambiguous between {', '.join(group)}: the bootstrap over cycles does not settle it; "
                   f"a {' or '.join(tests)} record would separate them")
        return finish("ambiguous", list(effs), flat, f.design, f.S, f.values)
    log.append(f"{best} is not stable over the cycle bootstrap ({100 * stats[best]['share']:.0f} %): verdict unexplained")
    return finish("unexplained", [], [], design, S0, {})


def _pair_eligible(t: dict) -> bool:
    """A pair's tests (``pair_test`` entry): (a) the partner's held-out chi^2
    drop over the nested reference exceeds its penalty (``nested_gain`` > 0);
    (b) the pair's held-out chi^2 + penalty (``abs``) is below each of its
    effects refitted alone (``alone_abs``); (c) each effect at its fitted
    values moves some record past its gate (``partner_ratio``, ``lead_ratio``
    >= 1; absent when the relevance tests are switched off)."""
    return (t["nested_gain"] > 0 and t["abs"] < min(t["alone_abs"].values())
            and t.get("partner_ratio", 1.0) >= 1.0 and t.get("lead_ratio", 1.0) >= 1.0)


def _pick(gain: dict, score: dict):
    """The winner among candidates with a positive held-out gain: the single
    effect with the largest gain over its own calibration (``gain``), replaced
    by a pair when a pair's absolute held-out chi^2 + penalty (``score``) is
    lower than that single's: the pair then describes the held-out data better
    than the best one-effect model, its partner having passed the nested test
    (eligibility). None when no candidate gains."""
    singles = [n for n in gain if "+" not in n and gain[n] > 0]
    best = max(singles, key=gain.get) if singles else None
    pairs = [n for n in gain if "+" in n and gain[n] > 0 and (best is None or score[n] < score[best])]
    return min(pairs, key=score.get) if pairs else best


def verdict_document(res: dict) -> dict:
    """``OUT/verdict.json`` (issue 11 interface, exactly these keys)."""
    return {"verdict": res["verdict"], "effects": list(res["effects"]), "group": list(res["group"]),
            "candidates": res["candidates"], "gap": res["gap"], "where": res["where"], "design": "design.yaml"}
