"""Concurrent sensitivity-weighted GAs (thesis Algorithm 1, issue 12) on a
cheap analytic model (no ODE)."""

import numpy as np
import pytest

from dampertwin.checkpoint import NpzStore

from dampertwin.calibration import sensitivity as sens
from dampertwin.calibration.concurrent import BatchScorer, GAGroup, run_concurrent
from dampertwin.calibration.ga import GASettings, ParamSpec

T = np.linspace(0.0, 3.0, 601)
QW = np.gradient(T) * 1.0  # quadrature weights [s] (trapezoid-like)
QW[0] = QW[-1] = (T[1] - T[0]) / 2
TRUTH = {"v1.a": 2.0, "v1.b": -1.0, "v2.a": 0.5, "v2.b": 3.0, "v3.a": 1.5, "oil.k": 0.8}
GROUPS = [GAGroup("v1", (ParamSpec("v1.a", 0.5, 4.0), ParamSpec("v1.b", -3.0, 1.0))),
          GAGroup("v2", (ParamSpec("v2.a", 0.1, 2.0, "log"), ParamSpec("v2.b", 0.0, 5.0))),
          GAGroup("v3", (ParamSpec("v3.a", 0.5, 3.0),)),
          GAGroup("compliance", (ParamSpec("oil.k", 0.2, 2.0),))]
KEYS = [s.key for g in GROUPS for s in g.specs]


def model(X):
    """Each 'valve' acts in its own phase of the signal (as valves open at
    different stages of a stroke); the 'compliance' everywhere."""
    X = np.atleast_2d(X)
    c = {k: X[:, i:i + 1] for i, k in enumerate(KEYS)}
    ph1, ph2, ph3 = (T < 1.0), (T >= 1.0) & (T < 2.0), T >= 2.0
    y = (ph1 * (c["v1.a"] * np.sin(3 * T) + c["v1.b"] * T)
         + ph2 * (c["v2.a"] * 3 * np.sin(6 * T) + c["v2.b"] * 0.3)
         + ph3 * c["v3.a"] * np.sin(5 * T) ** 2)
    return y + c["oil.k"] * np.sin(7 * T)


MEASURED = model(np.array([[TRUTH[k] for k in KEYS]]))[0]
W = np.vstack([(T < 1.0), (T >= 1.0) & (T < 2.0), T >= 2.0]).astype(float)  # stand-in sensitivity signals


def scorer(counter=None):
    def fn(X):
        if counter is not None:
            counter["rows"] += len(X)
            counter["calls"] += 1
            if counter.get("kill_at") and counter["calls"] >= counter["kill_at"]:
                raise KeyboardInterrupt("simulated kill")
        R = np.abs(MEASURED[None, :] - model(X))
        J = sens.weighted_integrals(R, QW, W)  # eq. 7.1 per valve group
        total = R @ QW  # unweighted: the compliance GA and the best-solution tracker
        return np.column_stack([J, total, total]), [None] * len(X)
    return fn


SETTINGS = GASettings(population=30, reproduction_ratio=80, generations=40, mutation_probability=20)


def test_recovers_known_parameters_one_simulation_per_individual():
    cnt = {"rows": 0, "calls": 0}
    res = run_concurrent(GROUPS, BatchScorer(scorer(cnt), 5), SETTINGS, seed=2, progress=False,
                         x0={k: s.lo + 0.5 * (s.hi - s.lo) for g in GROUPS for s in g.specs for k in [s.key]})
    for g in GROUPS:
        for s in g.specs:
            assert abs(res.best[s.key] - TRUTH[s.key]) < 0.06 * (s.hi - s.lo), (s.key, res.best[s.key])
    assert res.best_objective < 0.1 * res.start_objective
    # one simulation per distinct combined individual, never more
    assert cnt["rows"] == res.evaluations <= SETTINGS.population * (SETTINGS.generations + 1) + 1
    assert 1 <= res.best_evaluation <= res.evaluations
    h = res.history
    assert len(h) == SETTINGS.generations + 1
    assert np.all(np.diff(h["best unweighted so far"]) <= 0)
    assert set(res.best_group_objectives) == {"v1", "v2", "v3", "compliance"}


def test_resume_after_kill_gives_the_same_result(tmp_path):
    s = GASettings(population=12, reproduction_ratio=80, generations=8, mutation_probability=15)
    ref = run_concurrent(GROUPS, BatchScorer(scorer(), 5), s, seed=9, progress=False)
    ck = NpzStore(tmp_path / "ck.npz")
    with pytest.raises(TypeError, match="NpzStore"):  # the optimiser opens no file itself
        run_concurrent(GROUPS, BatchScorer(scorer(), 5), s, seed=9, progress=False, checkpoint=ck.path)
    with pytest.raises(KeyboardInterrupt):
        run_concurrent(GROUPS, BatchScorer(scorer({"rows": 0, "calls": 0, "kill_at": 5}), 5), s, seed=9,
                       progress=False, checkpoint=ck)
    assert ck.path.is_file()
    cnt = {"rows": 0, "calls": 0}
    res = run_concurrent(GROUPS, BatchScorer(scorer(cnt), 5), s, seed=9, progress=False, checkpoint=ck)
    assert cnt["calls"] < 9  # resumed, not restarted
    assert res.best == ref.best and res.best_objective == ref.best_objective
    assert res.evaluations == ref.evaluations and res.best_evaluation == ref.best_evaluation
    assert res.history.equals(ref.history)
    # a different seed does not reuse the checkpoint
    other = run_concurrent(GROUPS, BatchScorer(scorer(), 5), s, seed=10, progress=False, checkpoint=ck)
    assert other.best != ref.best


def test_failed_members_are_infeasible_not_fatal():
    def fn(X):
        S, why = scorer()(X)
        bad = X[:, 0] > 2.8  # v1.a too large: the "simulation" fails
        S[bad] = np.nan
        return S, ["simulation stopped: step cap" if b else None for b in bad]

    s = GASettings(population=10, reproduction_ratio=80, generations=3, mutation_probability=15)
    res = run_concurrent(GROUPS, BatchScorer(fn, 5), s, seed=1, progress=False)
    assert res.failed > 0 and "simulation stopped: step cap" in res.failures
    assert res.best["v1.a"] <= 2.8


def test_elites_are_rescored_with_their_new_partners():
    """Every combined individual is scored once; an individual is a new one
    (and simulated) as soon as one group's chromosome changes, e.g. an elite
    paired with another group's new elite."""
    seen = []

    def fn(X):
        seen.extend(map(bytes, np.round(X, 12)))  # parameter rows as evaluated
        return scorer()(X)

    s = GASettings(population=8, reproduction_ratio=75, generations=4, mutation_probability=15)
    res = run_concurrent(GROUPS, BatchScorer(fn, 5), s, seed=4, progress=False)
    assert len(seen) == len(set(seen)) == res.evaluations  # one simulation per distinct individual
    # every population is scored in full (cached or new): each generation brought new individuals
    assert (res.history["evaluations"].diff().dropna() > 0).all()


def test_dask_scheduler_runs_the_same_code_path():
    import distributed  # a dev dependency

    s = GASettings(population=8, reproduction_ratio=75, generations=3, mutation_probability=15)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as lc:
        sc = BatchScorer(scorer(), 5, scheduler=lc.scheduler_address, chunks=3)
        on_cluster = run_concurrent(GROUPS, sc, s, seed=6, progress=False)
        sc._map.close()
    local = run_concurrent(GROUPS, BatchScorer(scorer(), 5), s, seed=6, progress=False)
    assert on_cluster.best == local.best and on_cluster.best_objective == local.best_objective


def test_concurrent_gas_stop_once_converged():
    """With a stall window the concurrent GAs end before the budget once the
    best unweighted residual stops gaining, on the fixed budget's path."""
    from dataclasses import replace

    x0 = {s.key: s.lo + 0.5 * (s.hi - s.lo) for g in GROUPS for s in g.specs}
    a = run_concurrent(GROUPS, BatchScorer(scorer(), 5), SETTINGS, seed=2, progress=False, x0=x0)
    b = run_concurrent(GROUPS, BatchScorer(scorer(), 5), replace(SETTINGS, stall_generations=4, stall_tol=1e-2),
                       seed=2, progress=False, x0=x0)
    n = len(b.history) - 1
    assert n < SETTINGS.generations and b.evaluations < a.evaluations
    col = "best unweighted so far"
    assert b.history[col].iloc[:n].tolist() == a.history[col].iloc[:n].tolist()
    h = b.history[col].tolist()
    assert h[n - 5] - h[n - 1] <= 1e-2 * h[n - 5]
