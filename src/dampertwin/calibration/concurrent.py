"""Concurrently performed, sensitivity-based genetic algorithms (thesis 7.1,
Algorithm 1, L1452-1479).

One GA per parameter group (a valve; plus an unweighted group for gas
content and oil bulk modulus, thesis L1511). Each generation the k-th
chromosome of every group forms one individual: ONE simulation, scored once
per group (each group's own objective, e.g. eq. 7.1 with its sensitivity
weights) plus the unweighted residual. Selection, crossover and mutation run
per group on the group's own scores (the per-generation pygad engine of
:mod:`dampertwin.calibration.ga`, thesis 5.1.2 operators), then the groups'
new chromosomes are combined again. The best solution is tracked by the
unweighted residual ("fitness function without sensitivity signal");
the thesis fixes the number of generations; with the settings'
``stall_generations`` the GAs stop once that best has stopped gaining.

Engineering, as :func:`dampertwin.calibration.ga.run_ga`:
- a cache of scores keyed on the *combined* chromosome: an individual whose
  parts all reappear (e.g. elites paired with the same partners) is not
  simulated again, while an elite paired with new partners is a new
  individual and is re-scored (its group score depends on them);
- every random draw seeded by (seed, generation, group);
- a checkpoint per generation: a killed run resumed gives the same result;
- parallel evaluation: the whole population in one batch call (threads /
  ``simulate_batch`` locally), split over a Dask cluster when a scheduler
  address is configured.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from ..checkpoint import require_store
from .ga import INFEASIBLE, NEAR_SPREAD, FitError, FitResult, GASettings, ParamSpec, bound_hits


@dataclass(frozen=True)
class GAGroup:
    """One concurrent GA: its name and fitted quantities."""

    name: str
    specs: tuple[ParamSpec, ...]


class BatchScorer:
    """Scores a batch of combined parameter rows -> (S [m, G + 1], reasons):
    column g is group g's objective, the last column the unweighted one; a
    failed row is NaN. Local by default (the function itself runs the
    population in parallel, e.g. ``simulate_batch``); with a Dask scheduler
    address the batch is split into ``chunks`` mapped on the cluster."""

    def __init__(self, fn: Callable[[np.ndarray], tuple[np.ndarray, list]], n_scores: int,
                 scheduler: str | None = None, chunks: int = 4):
        from ..parallel import DaskMap

        self.fn, self.n, self.scheduler = fn, n_scores, scheduler
        self._map = DaskMap(scheduler, chunks) if scheduler else None

    def _check(self, out, m):
        S, why = out if isinstance(out, tuple) else (out, [None] * m)
        S = np.asarray(S, float)
        if S.shape != (m, self.n) or len(why) != m:
            raise ValueError(f"concurrent scorer returned {S.shape} scores for {m} members x {self.n} objectives")
        return S, [w if w or np.all(np.isfinite(s)) else "non-finite objective" for s, w in zip(S, why)]

    def __call__(self, X: np.ndarray) -> tuple[np.ndarray, list]:
        if self._map is None:
            return self._check(self.fn(X), len(X))
        outs = [self._check(r, len(x)) for r, x in self._map(self.fn, X)]
        return np.vstack([o[0] for o in outs]), [w for o in outs for w in o[1]]


@dataclass(frozen=True)
class ConcurrentSettings:
    """The concurrent GAs of :func:`.optimisers.run`: the GA settings each
    group's GA runs with (thesis tables 7.x: population, reproduction ratio,
    generations, mutation)."""

    ga: GASettings


def run_concurrent(groups: Sequence[GAGroup], score: BatchScorer, settings: GASettings, seed: int, *,
                   x0: dict[str, float] | None = None, checkpoint=None,
                   label: str = "concurrent GA", progress: bool = True, context: str = "") -> FitResult:
    """Algorithm 1. ``score`` maps combined parameter rows (columns: the
    groups' specs in order) to one objective per group plus the unweighted
    one. ``x0`` (the nominal design) is member 0 of every group. A
    checkpoint is reused only if groups, settings, seed, x0 and ``context``
    match. The result (the core's :class:`~.ga.FitResult`) is the best
    individual by the unweighted objective, with its per-group objectives
    (``best_group_objectives``) and the evaluation that found it
    (``best_evaluation``)."""
    import pygad
    from ..progress import progress as tqdm

    groups = list(groups)
    G = len(groups)
    sizes = [len(g.specs) for g in groups]
    specs = [s for g in groups for s in g.specs]
    P = settings.population
    cache: dict[bytes, np.ndarray] = {}
    found_at: dict[bytes, int] = {}
    counters = {"failed": 0, "evals": 0}
    failures: dict[str, int] = {}

    def values(C: np.ndarray) -> np.ndarray:
        return np.column_stack([s.to_value(C[:, j]) for j, s in enumerate(specs)])

    def objective(C: np.ndarray) -> np.ndarray:
        """(P, K) combined genes -> (P, G + 1) scores; one simulation per new individual."""
        keys = [c.tobytes() for c in C]
        todo, seen = [], set()
        for i, k in enumerate(keys):
            if k not in cache and k not in seen:
                todo.append(i)
                seen.add(k)
        if todo:
            S, why = score(values(C[todo]))
            for i, s, w in zip(todo, S, why):
                bad = w is not None or not np.all(np.isfinite(s))
                counters["evals"] += 1
                if bad:
                    counters["failed"] += 1
                    failures[str(w)] = failures.get(str(w), 0) + 1
                cache[keys[i]] = np.full(G + 1, INFEASIBLE) if bad else np.asarray(s, float)
                found_at[keys[i]] = counters["evals"]
        return np.array([cache[k] for k in keys])

    pops, g0 = _first_populations(np.random.default_rng(seed), specs, sizes, P, x0)
    start_gen, rows = 0, []
    store = require_store(checkpoint)  # no file I/O here: the stage passes a store
    sig = json.dumps({"groups": [[g.name, [s.state() for s in g.specs]] for g in groups], "ga": settings.__dict__,
                      "seed": seed, "x0": x0, "context": context}, sort_keys=True)
    z = store.load() if store else None
    if z is not None and str(z["sig"]) == sig:
        pops, start_gen, rows = _restore(z, G, cache, found_at, counters, failures)
    parents = max(2, int(round(P * settings.reproduction_ratio / 100.0)))

    def record(gen: int, S: np.ndarray) -> None:
        ok = S[:, -1] < INFEASIBLE
        best_so_far = min((v[-1] for v in cache.values()), default=float("nan"))
        row = {"generation": gen, "evaluations": counters["evals"], "failed": int(np.sum(~ok)),
               "best unweighted": float(S[:, -1].min()),
               "best unweighted so far": float(best_so_far)}
        for gi, g in enumerate(groups):
            row[f"best {g.name}"] = float(S[:, gi].min())
            row[f"mean {g.name}"] = float(np.mean(S[ok, gi])) if ok.any() else float("nan")
        rows.append(row)

    bar = tqdm(total=settings.generations, initial=start_gen, desc=label, disable=not progress, leave=False)
    for gen in range(start_gen, settings.generations):
        if settings.converged([r["best unweighted so far"] for r in rows]):  # resumed fits stop alike
            break
        S = objective(np.hstack(pops))  # Combine + Simulations + Fitness_g for every group
        record(gen, S)
        bar.set_postfix(best=f"{min(v[-1] for v in cache.values()):.4g}")
        new = []
        for gi, pop in enumerate(pops):  # Selection, Crossover, Mutation per group on its own scores
            fit = -S[:, gi]
            calls = {"n": 0}

            def fitness(ga, solutions, idx, fit=fit, calls=calls):
                calls["n"] += 1
                # first call: the current population, scored by the shared simulations;
                # later calls (pygad scoring its new population) are not used: the
                # new chromosomes are scored with their new partners next generation
                return list(fit[np.atleast_1d(idx)]) if calls["n"] == 1 else [0.0] * len(np.atleast_1d(idx))

            ga = pygad.GA(num_generations=1, num_parents_mating=parents, fitness_func=fitness,
                          fitness_batch_size=P, initial_population=pop.copy(),
                          gene_space={"low": 0.0, "high": 1.0}, parent_selection_type="sss",
                          keep_elitism=settings.elitism, crossover_type="single_point" if sizes[gi] > 1 else None,
                          mutation_type="random", mutation_probability=settings.mutation_probability / 100.0,
                          mutation_by_replacement=True,
                          random_seed=int((seed * 1_000_003 + gen * 101 + gi) % (2**31)), suppress_warnings=True)
            ga.run()
            new.append(np.asarray(ga.population, float))
        pops = new
        if store:
            store.save(_state(pops, gen + 1, rows, cache, found_at, counters, sig, failures))
        bar.update(1)
    bar.close()
    S = objective(np.hstack(pops))
    record(len(rows), S)
    best_key = min(cache, key=lambda k: (cache[k][-1], found_at[k]))
    if cache[best_key][-1] >= INFEASIBLE:
        raise FitError(f"{label}: every simulation failed ({counters['evals']} evaluations); reasons: {failures}")
    gb = np.frombuffer(best_key, dtype=float)
    best = {s.key: float(s.to_value(gb[j])) for j, s in enumerate(specs)}
    start = float(objective(g0[None, :])[0, -1]) if g0 is not None else float("nan")
    return FitResult(best, float(cache[best_key][-1]), start, pd.DataFrame(rows), counters["failed"],
                     counters["evals"], dict(failures), bound_hits=bound_hits(specs, best),
                     groups=[g.name for g in groups],
                     best_group_objectives={g.name: float(cache[best_key][gi]) for gi, g in enumerate(groups)},
                     best_evaluation=found_at[best_key])


def _first_populations(rng, specs: list, sizes: list, P: int, x0: dict | None) -> tuple[list, np.ndarray | None]:
    """Each group's first population (uniform in its genes) and, with the
    nominal design ``x0``, its genes ``g0``: member 0 of every group, half of
    each population around it."""
    cuts = np.cumsum([0] + sizes)
    pops = [rng.uniform(0, 1, (P, n)) for n in sizes]
    g0 = None
    if x0 is not None:
        g0 = np.array([s.to_gene(x0[s.key]) for s in specs])
        near = P // 2
        for gi, pop in enumerate(pops):
            part = g0[cuts[gi]:cuts[gi + 1]]
            pop[1:near] = np.clip(part + NEAR_SPREAD * rng.standard_normal((near - 1, sizes[gi])), 0, 1)
            pop[0] = part
    return pops, g0


def _restore(z, G: int, cache: dict, found_at: dict, counters: dict, failures: dict) -> tuple[list, int, list]:
    """A checkpoint's state (``_state``) back into the caches and counters; returns (populations,
    next generation, history rows)."""
    for k, s, n in zip(z["cache_keys"], z["cache_vals"], z["found_at"]):
        cache[bytes(k)] = np.asarray(s, float)
        found_at[bytes(k)] = int(n)
    counters["failed"], counters["evals"] = int(z["failed"]), int(z["evals"])
    failures.update(json.loads(str(z["failures"])))
    return [z[f"pop{gi}"] for gi in range(G)], int(z["gen"]), json.loads(str(z["history"]))


def _state(pops, gen, rows, cache, found_at, counters, sig, failures) -> dict:
    """The concurrent GAs' state for their checkpoint store."""
    keys = list(cache)
    K = np.array([np.frombuffer(k, dtype=np.uint8) for k in keys]) if keys else np.zeros((0, 0), np.uint8)
    return dict(**{f"pop{gi}": p for gi, p in enumerate(pops)}, gen=gen, history=json.dumps(rows),
                cache_keys=K, cache_vals=np.array([cache[k] for k in keys]),
                found_at=np.array([found_at[k] for k in keys], np.int64), failed=counters["failed"],
                evals=counters["evals"], sig=sig, failures=json.dumps(failures, sort_keys=True))


def progress_figure(history: pd.DataFrame, groups: Sequence[str], title: str = "Concurrent GAs (thesis fig. 7.7)"):
    """Best objective per group (sensitivity-scaled, left) and the
    unweighted residual (right) over the generations."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), constrained_layout=True)
    h = history[history["best unweighted"] < INFEASIBLE]
    for g in groups:
        axes[0].plot(h["evaluations"], h[f"best {g}"], label=g)
    axes[0].set(xlabel="evaluations (simulations)", ylabel="best J_g (eq. 7.1)", yscale="log",
                title="per-group sensitivity-scaled residual")
    axes[0].legend()
    axes[1].plot(h["evaluations"], h["best unweighted"], label="best in population")
    axes[1].plot(h["evaluations"], h["best unweighted so far"], "k--", label="best so far")
    axes[1].set(xlabel="evaluations (simulations)", ylabel="int |F_test - F_sim| dt [N s]", title="unweighted residual")
    axes[1].legend()
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    return fig


__all__ = ["GAGroup", "BatchScorer", "ConcurrentSettings", "run_concurrent", "progress_figure"]
