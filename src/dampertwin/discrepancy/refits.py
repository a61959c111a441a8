"""The discrepancy workflow's fitted quantities and refits: the candidate
effects and the calibration pool (:class:`~dampertwin.calibration.ga.ParamSpec`
each, with bounds, scale, start and prior), the parameter selection by
orthogonal matching pursuit, the sensitivity batch, the refits (the
calibration core's Gauss-Newton through
:func:`dampertwin.calibration.optimisers.run`) and what the records could
resolve. No I/O here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..calibration.ga import FitResult, ParamSpec
from ..calibration.gauss_newton import GaussNewtonSettings
from ..calibration.optimisers import run
from ..design import Design, DesignError
from .decision import record_chi2, worst_record
from .problem import Problem, RefitProblem, Row, nan_row


@dataclass
class Candidate:
    """An effect that may be missing: switch(es) + parameters at a typical magnitude."""

    name: str                       # effect name ("a+b" for a pair)
    effects: list
    params: list                    # ParamSpec of the effect's C parameters
    typical: dict                   # key -> typical value (C and F parameters)

    def overrides(self) -> dict:
        return {**{f"effects.{e}": True for e in self.effects}, **self.typical}


def calibration_params(design: Design, cfg: dict) -> list[ParamSpec]:
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
        out.append(ParamSpec.auto(key, lo, hi, float(p.value)))
    return out + _on_effect_params(design, {q.key for q in out})


def _on_effect_params(design: Design, have: set) -> list[ParamSpec]:
    """The C parameters of effects switched ON in the design (an effect added in an earlier
    round of the workflow, or by the engineer): calibrated like the pool's parameters, since
    they are part of the model now, not candidates (``catalogue`` leaves them out)."""
    out = []
    for e in design.effect_parameters() if hasattr(design, "effect_parameters") else ():
        if (design.effects.get(e.effect, False) and e.type == "C" and e.bounds is not None
                and e.key not in have and float(e.bounds[0]) < float(e.bounds[1])):
            out.append(ParamSpec.auto(e.key, float(e.bounds[0]), float(e.bounds[1]), float(design[e.key])))
    return out


def _lacking(design: Design) -> tuple[str, ...]:
    """Effects of parts the design's architecture has no part for (a passive damper's active-valve effects),
    and effects that modify an effect the design has off (schema.EFFECT_NEEDS: e.g. seal_friction_pressure
    without rod_friction): as candidates they would do nothing."""
    from ..design.architecture import ACTIVE_VALVE_EFFECTS
    from ..design.schema import EFFECT_NEEDS

    lacking = ACTIVE_VALVE_EFFECTS if design.pq_map is None else ()
    return lacking + tuple(e for e, need in EFFECT_NEEDS.items() if not design.effects.get(need, False))


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
            params = [ParamSpec.auto(e.key, float(e.bounds[0]), float(e.bounds[1]), float(e.typical))
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
            params.append(ParamSpec.auto(key, lo, hi, float(s["typical"])))
            typ[key] = float(s["typical"])
        cands[eff] = Candidate(eff, [eff], params, typ)
    return list(cands.values())


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



def with_priors(specs: list[ParamSpec], prior: dict) -> list[ParamSpec]:
    """``specs`` with the priors of ``prior`` (key -> (value [SI], sigma in u)), none for the other keys."""
    return [replace(p, prior=prior.get(p.key)) for p in specs]


def restarted(specs: list[ParamSpec], values: dict) -> list[ParamSpec]:
    """``specs`` starting from ``values`` where they have the key (else their own start)."""
    return [replace(p, start=values.get(p.key, p.start)) for p in specs]


def refit(problem: Problem, base: Design, fixed: dict, specs: list[ParamSpec], mask: np.ndarray,
          settings: GaussNewtonSettings, label: str, S0: Row | None = None, J0: dict | None = None) -> FitResult:
    """The calibration core's Gauss-Newton (:func:`~dampertwin.calibration.optimisers.run`)
    on the whitened features of ``mask``: ``specs`` (with their priors)
    overridden on ``base`` together with ``fixed``. ``S0``: the features at
    the specs' starts (no simulation for them); ``J0``: known Jacobian
    columns (key -> dz/du). The result carries the features at the fit
    (``simulated``), the Jacobian (``jacobian``), the fitted design and its
    overrides."""
    rp = RefitProblem(problem, base, fixed, [p.key for p in specs], mask, label)
    res = run(rp, specs, settings, label=label, start=None if S0 is None else (problem.z(S0), S0), jacobian=J0)
    res.design, res.overrides = rp.design_at([res.best[p.key] for p in specs])
    return res


def at_design(design: Design, S: Row) -> FitResult:
    """The design itself as a fit without parameters (the reference when its calibration refit does worse)."""
    import pandas as pd

    return FitResult({}, math.nan, math.nan, pd.DataFrame(), 0, 0, simulated=S, design=design)


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
    return [r if o else nan_row(r) for r, o in zip(S, ok)]


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
    return [r if o else nan_row(r) for r, o in zip(S, ok)], np.array(hs)


def misfit_beside(problem: Problem, s: np.ndarray, misfit_z: np.ndarray, mask: np.ndarray) -> dict:
    """Per-record chi^2 of the misfit ``misfit_z`` less its part along the signature ``s`` (a >= 0
    times ``s``, least squares over ``mask``): the model error beside an effect that may itself be
    in the records (an effect's magnitude is not negative)."""
    ss = float(np.sum(s[mask] ** 2))
    a = max(0.0, float(np.dot(misfit_z[mask], s[mask])) / ss) if ss > 0 else 0.0
    return record_chi2(problem, misfit_z - a * s, mask)


def resolvability(problem: Problem, base: Design, S_base: Row, cands: list, J: np.ndarray, prior_sigma: float,
                  alpha: float, separating: dict, misfit_z: np.ndarray | None = None) -> list[dict]:
    """What the records present can resolve: each candidate switched on at
    its typical magnitude on ``base``, its whitened signature (bench gain /
    offset allowances already in the whitening) minus what the calibration
    pool absorbs (columns ``J`` = d z / d u, prior width ``prior_sigma`` in
    u as in the refit), as chi^2 in its most affected record over that
    record's gate quantile (``worst_record``). ratio >= 1: the typical
    magnitude alone exceeds the gate; otherwise about 1 / sqrt(ratio) x the
    typical magnitude would be needed (signature linear in the magnitude).
    A `none` verdict says nothing about an effect with ratio << 1.

    ``misfit_z``: the whitened residual the calibrated design leaves (an
    `unexplained` verdict's model error). For each candidate, the part of it
    along the candidate's own signature (a >= 0 times it, least squares over
    every record: the effect itself, if present) is taken out first, so an
    effect in the records does not hide under its own residual; what remains
    inflates each record's gate by its Birge ratio (``worst_record``'s
    ``misfit``): ``ratio`` < 1 says the typical magnitude would hide under
    the model error of every record; ``ratio_noise`` / ``record_noise`` keep
    the test against the noise alone."""
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
        if misfit_z is not None:
            entry.update(ratio_noise=None, record_noise="")
        if np.all(np.isfinite(zs)) and np.all(np.isfinite(zb)):
            s = zb - zs   # the residual the effect would leave if the model lacked it
            if n:
                a = np.linalg.lstsq(A, np.concatenate([s, np.zeros(n)]), rcond=None)[0]
                s = s - J @ a
            misfit = misfit_beside(problem, s, misfit_z, allm) if misfit_z is not None else None
            ratio, rec = worst_record(problem, s, allm, alpha, misfit)
            entry.update(ratio=round(ratio, 4), record=rec, resolvable=bool(ratio >= 1.0),
                         min_factor=round(1.0 / math.sqrt(ratio), 3) if ratio > 0 else None)
            if misfit_z is not None:
                r0, rec0 = worst_record(problem, s, allm, alpha)
                entry.update(ratio_noise=round(r0, 4), record_noise=rec0)
        out.append(entry)
    return out


__all__ = ["Candidate", "calibration_params", "catalogue", "select_params", "with_priors", "restarted", "refit",
           "at_design", "sensitivity", "misfit_beside", "resolvability"]
