"""The discrepancy workflow's statistics and decisions: the training /
held-out folds, the whitened chi^2 and its per-record gate, where the
residual lies, and the tests that pick a named effect or pair. No I/O here.
"""

from __future__ import annotations

import math

import numpy as np

from ..calibration.problem import chi
from .problem import Problem


# report wording only: a held-out chi^2 within 10 % of its feature count is "at or near noise level",
# where a closed fraction of the (tiny) excess reads as an absurd percentage (-1666 %)
NEAR_NOISE = 1.1


def mean_z2(z: np.ndarray, mask: np.ndarray) -> float:
    n = int(np.sum(mask))
    return chi(z, mask) / max(n, 1)


def _blocks(problem: "Problem", z: np.ndarray, mask: np.ndarray) -> list:
    """(record key, its masked features of ``z``) for every record with a feature in ``mask``."""
    blocks, k = [], 0
    for u in problem.units:
        n = len(u.labels)
        m = mask[k:k + n]
        if m.any():
            blocks.append((u.key, z[k:k + n][m]))
        k += n
    return blocks


def record_chi2(problem: "Problem", z: np.ndarray, mask: np.ndarray) -> dict:
    """Sum of z^2 over each record's features in ``mask`` (record key -> chi^2)."""
    return {key: float(np.sum(v * v)) for key, v in _blocks(problem, z, mask)}


def worst_record(problem: "Problem", z: np.ndarray, mask: np.ndarray, alpha: float,
                 misfit: dict | None = None) -> tuple[float, str]:
    """Per-record chi-square test of the whitened residual: the largest ratio
    (sum of z^2 over a record's features) / (its chi-square quantile at
    1 - alpha / records, Bonferroni) and that record. A ratio above 1 is a
    disagreement localised in one record (the slowest curving run, say) that
    the mean over every feature would dilute; under the noise model the
    chance that any agreeing record exceeds it is <= alpha.

    ``misfit`` (record key -> chi^2 of a residual no parameter removes, the
    model error of that record): the record's noise is inflated by its Birge
    ratio B = misfit / features where B > 1 (the Particle Data Group's scale
    factor S = sqrt(B), applied when S > 1), so its gate becomes B x its
    quantile: a signature counts only where it stands out of the noise and
    of the misfit already there. Records with B <= 1 keep their quantile.
    """
    from scipy.stats import chi2 as chi2_dist

    blocks = _blocks(problem, z, mask)
    worst, key = 0.0, ""
    q = 1.0 - alpha / max(len(blocks), 1)
    quant = {n: float(chi2_dist.ppf(q, n)) for n in {len(v) for _, v in blocks}}
    for name, v in blocks:
        gate = quant[len(v)] * max(1.0, (misfit or {}).get(name, 0.0) / len(v))
        val = float(np.sum(v * v)) / gate if np.all(np.isfinite(v)) else math.inf
        if val > worst:
            worst, key = val, name
    return worst, key


def closed_where_reached(problem: "Problem", z_ref: np.ndarray, z_fit: np.ndarray, z_off: np.ndarray,
                         mask: np.ndarray, alpha: float) -> tuple[float, list]:
    """Fraction of the excess chi^2 over noise (chi^2 - features) that a fit
    closes, counted on the records its fitted effect reaches: those where the
    effect's own signature (``z_off`` - ``z_fit``: the fit with its effect(s)
    switched off at its calibration values, as the nested model) exceeds the
    record's chi-square quantile at 1 - alpha / records (``worst_record``'s
    gate). Records the effect cannot move are left out of numerator and
    denominator: their misfit (the model error of other physics) is for
    another round, and on the whole held-out gap it would hide an effect that
    explains its own records (truth 3, 1.5x free play: 66 % of its record's
    excess, 32 % of the whole gap). Returns (fraction, reached record keys);
    (0.0, []) when no record is reached or their excess is not positive."""
    from scipy.stats import chi2 as chi2_dist

    ref, fit, sig = (dict(_blocks(problem, z, mask)) for z in (z_ref, z_fit, z_off - z_fit))
    q = 1.0 - alpha / max(len(ref), 1)
    reached = [k for k, v in sig.items() if np.all(np.isfinite(v))
               and float(np.sum(v * v)) >= float(chi2_dist.ppf(q, len(v)))]
    num = sum(float(np.sum(ref[k] ** 2) - np.sum(fit[k] ** 2)) for k in reached)
    den = sum(float(np.sum(ref[k] ** 2)) - len(ref[k]) for k in reached)
    if not reached or not den > 0 or not math.isfinite(num):
        return 0.0, []
    return num / den, reached


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


def _pair_eligible(t: dict) -> bool:
    """A pair's tests (``pair_test`` entry): (a) the partner's held-out chi^2
    drop over the nested reference exceeds its penalty (``nested_gain`` > 0);
    (b) the pair's held-out chi^2 + penalty (``abs``) is below each of its
    effects refitted alone (``alone_abs``); (c) each effect at its fitted
    values moves some record past its gate (``partner_ratio``, ``lead_ratio``
    >= 1; absent when the relevance tests are switched off)."""
    return (t["nested_gain"] > 0 and t["abs"] < min(t["alone_abs"].values())
            and t.get("partner_ratio", 1.0) >= 1.0 and t.get("lead_ratio", 1.0) >= 1.0)


def viable(names: list, stats: dict, min_closed: float) -> list:
    """The fits the closure gate passes: a positive penalised held-out gain
    and at least ``min_closed`` of their gap closed (``stats[n]["closed"]``)."""
    return [n for n in names if stats[n]["gain"] > 0 and stats[n]["closed"] >= min_closed]


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



__all__ = ["NEAR_NOISE", "chi", "mean_z2", "worst_record", "record_chi2", "closed_where_reached",
           "assign_folds", "viable"]
