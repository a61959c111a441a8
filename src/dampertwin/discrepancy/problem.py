"""The discrepancy workflow's records problem: prepared units, their noise
model, batched simulations of designs (a :class:`Row` of features per
design) and the whitened residuals z; and :class:`RefitProblem`, the
calibration core's problem (:class:`~dampertwin.calibration.problem.Problem`)
over one base design and a set of overridden keys, which the refits hand to
:func:`dampertwin.calibration.optimisers.run`. No I/O here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..calibration.problem import Problem as CoreProblem
from ..calibration.problem import WhitenedChi2
from ..design import Design, DesignError
from ..simulation import simulate_batch
from . import features as F


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



def nan_row(r: Row) -> Row:
    """``r`` with every feature NaN (a member that could not be simulated)."""
    return Row([np.full_like(p, np.nan) for p in r.pcs])


class RefitProblem(CoreProblem):
    """Parameter rows (values of ``keys``) -> whitened residual rows z of
    ``problem`` (NaN rows for failed members), the simulated features per
    row as output; designs are ``base`` with ``fixed`` and the row's values
    as overrides. Cost: the whitened chi^2 over ``mask``
    (:class:`~dampertwin.calibration.problem.WhitenedChi2`)."""

    def __init__(self, problem: Problem, base: Design, fixed: dict, keys: list, mask: np.ndarray,
                 label: str = "refit"):
        self.problem, self.base, self.fixed, self.keys, self.label = problem, base, dict(fixed), list(keys), label
        self.cost = WhitenedChi2(mask)

    def design_at(self, x) -> tuple[Design, dict]:
        """(design, overrides) at the parameter values ``x``; DesignError outside the valid set."""
        ov = {**self.fixed, **dict(zip(self.keys, x))}
        return self.base.with_overrides(ov), ov

    def invalid(self, x) -> str | None:
        try:
            self.design_at(x)
        except DesignError as e:
            return str(e)
        return None

    def evaluate(self, X: np.ndarray):
        rows = self.problem.simulate([self.design_at(x)[0] for x in X], label=self.label)
        Z = np.array([self.problem.z(r) for r in rows])
        return Z, [None if np.all(np.isfinite(z)) else "simulation failed" for z in Z], rows

    def failed_output(self, output: Row) -> Row:
        return nan_row(output)


__all__ = ["Row", "Problem", "RefitProblem", "simulate_unit", "record_pool", "nan_row"]
