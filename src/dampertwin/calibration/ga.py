"""Genetic-algorithm fits (pygad) with the engineering a long calibration
needs: the whole population evaluated per generation in one batch call
(threads locally, a Dask cluster when configured), failed simulations scored
as infeasible and counted, a tqdm bar with the best objective, a checkpoint
per generation (a killed fit resumes where it stopped and ends with the same
result), and every random draw seeded.

Genes live in [0, 1] and map to each parameter's bounds, linearly or
logarithmically. pygad runs one generation per instance, seeded with
(seed, generation), so an interrupted and resumed fit equals an uninterrupted
one. Thesis 5.1.2: steady-state parent selection, single-point crossover,
random mutation, elitism.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import pandas as pd

from ..checkpoint import require_store
from ..errors import UserError

INFEASIBLE = 1e30  # objective of a failed simulation
TOP_KEPT = 10  # best distinct members returned (start points of a local polish)
# a fitted value within this fraction of its search interval (the gene's [0, 1]) from an end is "on the
# bound": a GA's best member rarely sits exactly on it, and 2 % of the window is inside a GA's final spread
NEAR_BOUND = 0.02


class FitError(UserError):
    """A fit that cannot run or produce a result: unusable inputs (the
    message names the file / key / item) or every member infeasible. The
    one fit error of the project."""
NEAR_SPREAD = 0.1  # gene-space std of the initial members placed around the nominal design


@dataclass(frozen=True)
class ParamSpec:
    """A fitted quantity: design key, search bounds (SI), scale of its
    normalised coordinate in [0, 1] (the GA's gene, the Gauss-Newton refit's
    u), optionally its start value and its prior. The one parameter spec of
    the calibration core (the discrepancy refits build theirs with
    :meth:`auto`)."""

    key: str
    lo: float
    hi: float
    scale: str = "lin"  # "lin" | "log" (log: lo, hi of one sign, uniform in log |value|)
    start: float | None = None  # start value [SI] (None: the design's)
    # Gaussian prior (value [SI], sigma in the normalised coordinate u): the Gauss-Newton refits' Tikhonov
    # rows (u - u(value)) / sigma; None: no prior (the GAs search the bounds alone)
    prior: tuple[float, float] | None = None

    @classmethod
    def auto(cls, key: str, lo: float, hi: float, start: float | None = None,
             prior: tuple[float, float] | None = None) -> "ParamSpec":
        """Logarithmic when the bounds are positive and span > 2 decades."""
        return cls(key, lo, hi, "log" if lo > 0 and hi / lo > 100 else "lin", start, prior)

    def state(self) -> dict:
        """The fields as a dict for a checkpoint's signature (``prior`` only when set: a fit without
        priors keeps the signature it had before specs carried them)."""
        d = dict(self.__dict__)
        if d["prior"] is None:
            del d["prior"]
        return d

    @property
    def log(self) -> bool:
        return self.scale == "log"

    def to_u(self, v: float) -> float:
        """Scalar value -> coordinate in [0, 1] (clipped to the bounds)."""
        v = min(max(v, self.lo), self.hi)
        if self.log:
            return math.log(v / self.lo) / math.log(self.hi / self.lo)
        return (v - self.lo) / (self.hi - self.lo) if self.hi > self.lo else 0.0

    def to_v(self, u: float) -> float:
        """Scalar coordinate (clipped to [0, 1]) -> value."""
        u = min(max(u, 0.0), 1.0)
        if self.log:
            return self.lo * (self.hi / self.lo) ** u
        return self.lo + u * (self.hi - self.lo)

    def to_value(self, g):
        g = np.clip(g, 0.0, 1.0)
        if self.scale == "log":
            return self.lo * (self.hi / self.lo) ** g
        return self.lo + (self.hi - self.lo) * g

    def to_gene(self, v):
        if self.scale == "log":
            return self.to_u(float(v))
        return float(np.clip((v - self.lo) / (self.hi - self.lo), 0, 1))


GA_KEYS = {"population", "reproduction_ratio", "generations", "mutation_probability", "elitism", "max_wall_s",
           "stall_generations", "stall_tol"}  # what a GA settings mapping may say (GASettings' fields)


@dataclass(frozen=True)
class GASettings:
    """Thesis tables 6.2 / 6.3: population, reproduction ratio [%],
    generations, mutation probability [%]."""

    population: int
    reproduction_ratio: float
    generations: int
    mutation_probability: float
    elitism: int = 1
    max_wall_s: float | None = None  # wall-time cap [s] of one population's simulations
    # convergence stop: end when the best objective has gained no more than stall_tol (relative) over the last
    # stall_generations generations (None: the fixed budget of the thesis' tables 6.2 / 6.3)
    stall_generations: int | None = None
    stall_tol: float = 0.0

    @classmethod
    def from_config(cls, c, where: str = "GA settings") -> "GASettings":
        """Settings from a mapping (a profile's or a --bounds file's ``ga:``
        over the defaults); every key checked for type and range before any
        simulation: a UserError naming ``where`` (the file), ``ga.<key>``
        and what was expected."""
        unknown = set(c) - GA_KEYS
        if unknown:
            raise UserError(f"{where}: ga: unknown key(s) {', '.join(sorted(map(str, unknown)))}; expected "
                            f"{', '.join(sorted(GA_KEYS))}")

        def bad(key: str, expected: str) -> UserError:
            return UserError(f"{where}: ga.{key} {c.get(key)!r}; expected {expected}")

        def integer(v) -> bool:
            return isinstance(v, (int, np.integer)) and not isinstance(v, bool)

        def number(v) -> bool:
            return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) \
                and math.isfinite(v)

        for key in ("population", "generations"):
            if not integer(c.get(key)) or c[key] < (2 if key == "population" else 1):
                raise bad(key, f"an integer >= {2 if key == 'population' else 1}")
        pop = int(c["population"])
        for key, what in (("reproduction_ratio", "the share of the population mating [%]"),
                          ("mutation_probability", "the probability a gene mutates [%]")):
            if not number(c.get(key)) or not 0 < c[key] <= 100:
                raise bad(key, f"{what} in (0, 100]")
        el = c.get("elitism", 1)
        if not integer(el) or not 0 <= el < pop:
            raise bad("elitism", f"an integer 0 <= elitism < population ({pop}): the best members kept")
        wall = c.get("max_wall_s")
        if not number(wall) or not wall > 0:
            raise bad("max_wall_s", "a positive wall-time cap [s] for one population's simulations "
                                    "(conf/profile/*.yaml)")
        k, tol = c.get("stall_generations"), c.get("stall_tol", 0.0)
        if k is not None and (not integer(k) or k < 1):
            raise bad("stall_generations", "a positive integer (generations without gain before the GA stops) "
                                           "or null (conf/profile/*.yaml)")
        if not number(tol) or not 0 <= tol < 1:
            raise bad("stall_tol", "a relative gain in [0, 1) (conf/profile/*.yaml)")
        return cls(pop, float(c["reproduction_ratio"]), int(c["generations"]), float(c["mutation_probability"]),
                   int(el), float(wall), None if k is None else int(k), float(tol))

    def converged(self, best: list[float]) -> bool:
        """True when the best objective per generation so far (``best``,
        non-increasing with elitism) gained no more than ``stall_tol`` of its
        value over the last ``stall_generations`` generations."""
        k = self.stall_generations
        if k is None or len(best) <= k:
            return False
        old, new = min(best[:-k]), min(best)
        return old - new <= self.stall_tol * abs(old)


@dataclass
class FitResult:
    """What every optimiser of the core returns (:func:`.optimisers.run`):
    the fitted values, the objective at them and at the start, the objective
    history, the failed members and their reasons; the optional fields are
    set by the optimisers that have them (polish, uncertainty, the
    concurrent GAs' per-group objectives, the Gauss-Newton's output and
    Jacobian at the fit)."""

    best: dict[str, float]
    best_objective: float
    start_objective: float
    history: pd.DataFrame
    failed: int
    evaluations: int
    failures: dict = field(default_factory=dict)  # reason -> count of infeasible members
    top: list[np.ndarray] = field(default_factory=list)  # genes of the best distinct members, best first
    objective_ga: float = float("nan")  # best objective of the GA alone (before any local polish)
    polish: dict = field(default_factory=dict)  # local polish report (calibration.polish)
    uncertainty: dict = field(default_factory=dict)  # calibration.uncertainty at the optimum
    specs: list = field(default_factory=list)  # the fitted quantities (set by the approach-1 fits)
    records: object = None  # calibration.polish.Records of the fit: re-evaluates its objective
    bound_hits: list = field(default_factory=list)  # fitted values on an end of their search interval (bound_hits)
    # concurrent GAs (calibration.concurrent): the groups, the best individual's objective per group and the
    # 1-based index of the evaluation (simulation) that found it ("iteration 2639")
    groups: list = field(default_factory=list)
    best_group_objectives: dict = field(default_factory=dict)
    best_evaluation: int | None = None
    # Gauss-Newton (calibration.gauss_newton): the problem's output at the fit (the simulated features), the
    # Broyden-updated Jacobian (key -> dz/du) and, set by the caller, the fitted model and its overrides
    simulated: object = None
    jacobian: dict = field(default_factory=dict)
    design: object = None
    overrides: dict = field(default_factory=dict)


def bound_hits(specs: list[ParamSpec], values: dict[str, float], *, tol: float = NEAR_BOUND,
               kind: Callable[[int, int], str] | None = None) -> list[dict]:
    """The fitted values within ``tol`` of an end of their search interval
    (in gene space, so a log-scale interval counts in decades): parameter,
    bound (lower / upper), value and limit [SI], and ``kind`` of the bound
    (``kind(i, end)`` for spec i, end 0 = lower; default "search"). A value
    there says the optimum may lie beyond the interval, or that the
    parameter stands in for something the model lacks."""
    out = []
    for i, s in enumerate(specs):
        v = float(values[s.key])
        g = s.to_gene(v) if (s.scale != "log" or v / s.lo > 0) else 0.0
        for end, near in ((0, g <= tol), (1, g >= 1.0 - tol)):
            if near:
                out.append({"parameter": s.key, "bound": "lower" if end == 0 else "upper", "value": v,
                            "limit": s.lo if end == 0 else s.hi, "kind": "search" if kind is None else kind(i, end)})
    return out


def split_scores(r, n: int) -> tuple[np.ndarray, list]:
    """An objective's return value -> (values, reasons). A batch objective
    may return the values alone or ``(values, reasons)`` where reasons[i]
    says why member i failed (None if it did not)."""
    if isinstance(r, tuple) and len(r) == 2:
        J, reasons = np.asarray(r[0], float), list(r[1])
    else:
        J, reasons = np.asarray(r, float), [None] * n
    if J.shape != (n,) or len(reasons) != n:
        raise ValueError(f"batch objective returned {J.shape} values for {n} members")
    return J, [why if why or np.isfinite(j) else "non-finite objective" for j, why in zip(J, reasons)]


class Evaluator:
    """Evaluates a batch of parameter rows -> (objective values, failure
    reasons); NaN = failed. Local by default; with a Dask scheduler address
    the same batches are split into chunks and mapped on the cluster."""

    def __init__(self, batch_objective: Callable[[np.ndarray], np.ndarray], scheduler: str | None = None,
                 chunks: int = 4):
        from ..parallel import DaskMap

        self.f = batch_objective
        self.scheduler = scheduler
        self._map = DaskMap(scheduler, chunks) if scheduler else None

    def __call__(self, X: np.ndarray) -> tuple[np.ndarray, list]:
        if self._map is None:
            return split_scores(self.f(X), len(X))
        out = [split_scores(r, len(x)) for r, x in self._map(self.f, X)]
        return np.concatenate([o[0] for o in out]), [w for o in out for w in o[1]]


def run_ga(specs: list[ParamSpec], evaluate: Evaluator, settings: GASettings, seed: int, *,
           x0: dict[str, float] | None = None, checkpoint=None, label: str = "fit",
           progress: bool = True, context: str = "") -> FitResult:
    """Minimise the objective over ``specs``. ``x0`` (the nominal design) is
    a member of the first population and gives ``start_objective``. A
    checkpoint is reused only if specs, settings, seed, x0 and ``context``
    (a hash of the inputs: design, measured data) all match. ``checkpoint``:
    a store (:mod:`dampertwin.checkpoint`, e.g. ``NpzStore(path)``; not a
    path: no file I/O here); the GA saves its state there after every
    generation."""
    import pygad
    from ..progress import progress as tqdm

    k = len(specs)
    cache: dict[bytes, float] = {}
    counters = {"failed": 0, "evals": 0}
    failures: dict[str, int] = {}

    def values(G: np.ndarray) -> np.ndarray:
        return np.column_stack([s.to_value(G[:, j]) for j, s in enumerate(specs)])

    def objective(G: np.ndarray) -> np.ndarray:
        G = np.atleast_2d(np.asarray(G, float))
        keys = [g.tobytes() for g in G]
        todo = [i for i, key in enumerate(keys) if key not in cache]
        if todo:
            J, reasons = evaluate(values(G[todo]))
            for i, j, why in zip(todo, J, reasons):
                bad = not np.isfinite(j)
                counters["failed"] += bad
                if bad:  # infeasible member: its reason is counted, the rest of the population is scored
                    failures[str(why)] = failures.get(str(why), 0) + 1
                cache[keys[i]] = INFEASIBLE if bad else float(j)
            counters["evals"] += len(todo)
        return np.array([cache[key] for key in keys])

    def fitness(ga, solutions, idx):
        return list(-objective(np.asarray(solutions)))

    rng = np.random.default_rng(seed)
    pop = rng.uniform(0, 1, (settings.population, k))
    g0 = None
    if x0 is not None:
        # the nominal design and, for half of the population, perturbations of
        # it: an engineer starts from the drawings, the rest explores
        g0 = np.array([s.to_gene(x0[s.key]) for s in specs])
        near = settings.population // 2
        pop[1:near] = np.clip(g0 + NEAR_SPREAD * rng.standard_normal((near - 1, k)), 0, 1)
        pop[0] = g0
    start_gen, rows = 0, []
    store = require_store(checkpoint)
    sig = json.dumps({"specs": [s.state() for s in specs], "ga": settings.__dict__, "seed": seed, "x0": x0,
                      "context": context}, sort_keys=True)
    z = store.load() if store else None
    if z is not None:
        if str(z["sig"]) == sig:
            pop, start_gen = z["pop"], int(z["gen"])
            rows = json.loads(str(z["history"]))
            for key, j in zip(z["cache_keys"], z["cache_vals"]):
                cache[bytes(key)] = float(j)
            counters["failed"], counters["evals"] = int(z["failed"]), int(z["evals"])
            if "failures" in z:
                failures.update(json.loads(str(z["failures"])))
    parents = max(2, int(round(settings.population * settings.reproduction_ratio / 100.0)))
    bar = tqdm(total=settings.generations, initial=start_gen, desc=label, disable=not progress, leave=False)
    for gen in range(start_gen, settings.generations):
        if settings.converged([r["best"] for r in rows]):  # from the history alone: a resumed fit stops alike
            break
        J = objective(pop)
        rows.append({"generation": gen, "best": float(J.min()), "mean": float(np.mean(J[J < INFEASIBLE]))
                     if np.any(J < INFEASIBLE) else float("nan"), "failed": int(np.sum(J >= INFEASIBLE))})
        bar.set_postfix(best=f"{J.min():.4g}")
        ga = pygad.GA(num_generations=1, num_parents_mating=parents, fitness_func=fitness,
                      fitness_batch_size=len(pop), initial_population=pop.copy(),
                      gene_space={"low": 0.0, "high": 1.0}, parent_selection_type="sss",
                      keep_elitism=settings.elitism, crossover_type="single_point", mutation_type="random",
                      mutation_probability=settings.mutation_probability / 100.0, mutation_by_replacement=True,
                      random_seed=int((seed * 1_000_003 + gen) % (2**31)), suppress_warnings=True)
        ga.run()
        pop = np.asarray(ga.population, float)
        if store:
            store.save(_state(pop, gen + 1, rows, cache, counters, sig, failures))
        bar.update(1)
    bar.close()
    J = objective(pop)
    rows.append({"generation": len(rows), "best": float(J.min()),
                 "mean": float(np.mean(J[J < INFEASIBLE])) if np.any(J < INFEASIBLE) else float("nan"),
                 "failed": int(np.sum(J >= INFEASIBLE))})
    ranked = sorted((k_ for k_ in cache if cache[k_] < INFEASIBLE), key=cache.get) or [min(cache, key=cache.get)]
    best_key = ranked[0]
    gb = np.frombuffer(best_key, dtype=float)
    best = {s.key: float(s.to_value(gb[j])) for j, s in enumerate(specs)}
    start = float(objective(g0[None, :])[0]) if g0 is not None else float("nan")
    if cache[best_key] >= INFEASIBLE:
        raise FitError(f"{label}: every simulation of the fit failed ({counters['evals']} evaluations); "
                           f"reasons: {failures}")
    top = [np.frombuffer(k_, dtype=float).copy() for k_ in ranked[:TOP_KEPT]]
    return FitResult(best, cache[best_key], start, pd.DataFrame(rows), counters["failed"], counters["evals"],
                     dict(failures), top=top, objective_ga=cache[best_key])


def _state(pop, gen, rows, cache, counters, sig, failures=None) -> dict:
    """The GA's state for its checkpoint store."""
    keys = np.array([np.frombuffer(k, dtype=np.uint8) for k in cache]) if cache else np.zeros((0, 0), np.uint8)
    return dict(pop=pop, gen=gen, history=json.dumps(rows), cache_keys=keys,
                cache_vals=np.array(list(cache.values())), failed=counters["failed"], evals=counters["evals"], sig=sig,
                failures=json.dumps(failures or {}, sort_keys=True))
