"""The GA engine: seeded, improves, counts failures, resumes after a kill."""

from __future__ import annotations

import numpy as np
import pytest

from dampertwin.calibration.ga import Evaluator, GASettings, ParamSpec, run_ga
from dampertwin.checkpoint import NpzStore

SPECS = [ParamSpec("x", -2.0, 2.0), ParamSpec("y", 0.01, 10.0, "log")]
SETTINGS = GASettings(population=16, reproduction_ratio=80, generations=12, mutation_probability=10)


def bowl(X):
    """A smooth objective with its minimum 0 at x = 0.5, y = 2; NaN (a failed
    simulation) where x < -1.5."""
    J = (X[:, 0] - 0.5) ** 2 + np.log(X[:, 1] / 2.0) ** 2
    J[X[:, 0] < -1.5] = np.nan
    return J


def test_param_spec_maps_genes_to_bounds():
    s = ParamSpec("k", 100.0, 1e4, "log")
    assert s.to_value(0.0) == pytest.approx(100.0) and s.to_value(1.0) == pytest.approx(1e4)
    assert s.to_value(0.5) == pytest.approx(1e3)
    assert s.to_gene(1e3) == pytest.approx(0.5)
    # a negative interval on a log scale is uniform in log |value| (a spring exponent d of eq. 4.19)
    n = ParamSpec("d", -1e5, -1e3, "log")
    assert n.to_value(0.0) == pytest.approx(-1e5) and n.to_value(1.0) == pytest.approx(-1e3)
    assert n.to_value(0.5) == pytest.approx(-1e4) and n.to_gene(-1e4) == pytest.approx(0.5)
    assert n.to_u(n.to_v(0.3)) == pytest.approx(0.3) and n.to_gene(0.0) == 1.0  # clipped into the interval


def test_ga_improves_on_the_start_is_seeded_and_counts_failures():
    x0 = {"x": -1.9, "y": 0.05}  # a poor, infeasible start
    a = run_ga(SPECS, Evaluator(bowl), SETTINGS, seed=3, x0=x0, progress=False)
    b = run_ga(SPECS, Evaluator(bowl), SETTINGS, seed=3, x0=x0, progress=False)
    c = run_ga(SPECS, Evaluator(bowl), SETTINGS, seed=4, x0=x0, progress=False)
    assert a.best == b.best and a.best_objective == b.best_objective  # same seed, same result
    assert a.best != c.best
    assert a.start_objective > 1e29  # the start was infeasible: scored as such, no crash
    assert a.failed >= 1 and a.evaluations > a.failed
    assert a.best_objective < 0.05
    assert list(a.history.generation) == list(range(SETTINGS.generations + 1))
    assert (np.diff(a.history.best) <= 1e-12).all()  # elitism: the best never gets worse


def test_killed_fit_resumes_to_the_same_result(tmp_path):
    ck = tmp_path / "ck.npz"
    calls = {"n": 0}

    def dying(X):
        calls["n"] += 1
        if calls["n"] == 6:
            raise KeyboardInterrupt  # the stage is killed mid-fit
        return bowl(X)

    with pytest.raises(KeyboardInterrupt):
        run_ga(SPECS, Evaluator(dying), SETTINGS, seed=7, checkpoint=NpzStore(ck), progress=False)
    assert ck.is_file()
    resumed = run_ga(SPECS, Evaluator(bowl), SETTINGS, seed=7, checkpoint=NpzStore(ck), progress=False)
    fresh = run_ga(SPECS, Evaluator(bowl), SETTINGS, seed=7, progress=False)
    assert resumed.best == fresh.best and resumed.best_objective == fresh.best_objective
    # a checkpoint of other inputs is not reused
    other = run_ga(SPECS, Evaluator(bowl), SETTINGS, seed=7, checkpoint=NpzStore(ck), progress=False, context="other data")
    assert other.best == fresh.best


def test_checkpoints_go_through_the_store_passed_in(tmp_path, monkeypatch):
    """The GA saves its state to the store it is given, once per generation,
    and resumes from it; it opens no file itself."""
    import builtins

    from dampertwin.checkpoint import MemoryStore

    store = MemoryStore()
    calls = {"n": 0}

    def dying(X):
        calls["n"] += 1
        if calls["n"] == 6:
            raise KeyboardInterrupt
        return bowl(X)

    real_open = builtins.open
    monkeypatch.setattr(builtins, "open", lambda *a, **k: (_ for _ in ()).throw(AssertionError(f"open{a}")))
    monkeypatch.setattr(np, "savez", lambda *a, **k: (_ for _ in ()).throw(AssertionError("np.savez")))
    with pytest.raises(KeyboardInterrupt):
        run_ga(SPECS, Evaluator(dying), SETTINGS, seed=7, checkpoint=store, progress=False)
    assert 1 <= store.saves == int(store.state["gen"]) < SETTINGS.generations  # killed mid-fit
    resumed = run_ga(SPECS, Evaluator(bowl), SETTINGS, seed=7, checkpoint=store, progress=False)
    monkeypatch.setattr(builtins, "open", real_open)
    fresh = run_ga(SPECS, Evaluator(bowl), SETTINGS, seed=7, progress=False)
    assert resumed.best == fresh.best and resumed.best_objective == fresh.best_objective
    assert store.saves == SETTINGS.generations


def test_the_ga_refuses_a_checkpoint_path(tmp_path):
    """A path is not a store: the GA does no file I/O, the caller opens the
    file store (NpzStore); the error names what to pass."""
    with pytest.raises(TypeError, match="NpzStore"):
        run_ga(SPECS, Evaluator(bowl), SETTINGS, seed=7, checkpoint=tmp_path / "ck.npz", progress=False)
    assert not (tmp_path / "ck.npz").exists()


def test_dask_scheduler_runs_the_same_code_path():
    """With a scheduler address the population is split into chunks mapped on
    a Dask cluster (here an in-process LocalCluster): same fit, same result."""
    import distributed  # a dev dependency

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as lc:
        ev = Evaluator(bowl, scheduler=lc.scheduler_address, chunks=3)
        on_cluster = run_ga(SPECS, ev, SETTINGS, seed=5, progress=False)
        ev._map.close()
    local = run_ga(SPECS, Evaluator(bowl), SETTINGS, seed=5, progress=False)
    assert on_cluster.best == local.best and on_cluster.best_objective == local.best_objective


def test_bad_calibration_config_names_file_and_item():
    from conftest import BASELINE

    from dampertwin.calibration.approach1 import specs_from_config
    from dampertwin.design import load

    d = load(BASELINE)
    ok = specs_from_config(d, [{"name": "a", "window": [0.5, 2.0]}], prefix="piston_rebound.", where="v.yaml")
    assert ok[0].lo == pytest.approx(150.0) and ok[0].hi == pytest.approx(600.0)
    (neg,) = specs_from_config(d, [{"name": "d", "window": [0.1, 10.0], "scale": "log"}], prefix="piston_rebound.")
    assert (neg.lo, neg.hi, neg.scale) == (-1e5, pytest.approx(-1500.0), "log")  # clipped to table 6.1's -1e5
    for bad, why in (([{"name": "zz", "window": [0.5, 2]}], "unknown design parameter"),
                     ([{"name": "a"}], "exactly one of"),
                     ([{"name": "a", "window": [0.5, 2], "scale": "cubic"}], "scale"),
                     ([{"name": "c", "bounds": [-100.0, 100.0], "scale": "log"}], "bounds of one sign"),
                     ([{"name": "d", "bounds": [-1e4, 0.0], "scale": "log"}], "bounds of one sign"),
                     ([], "non-empty list")):
        with pytest.raises(ValueError, match=why) as ei:
            specs_from_config(d, bad, prefix="piston_rebound.", where="v.yaml")
        assert "v.yaml" in str(ei.value)


# ------------------------------------------------------------ convergence stop (profile `full`)
def test_converged_reads_the_gain_over_the_last_generations():
    s = GASettings(16, 80, 40, 10, stall_generations=3, stall_tol=0.01)
    assert not s.converged([10.0, 9.0, 9.0])  # fewer generations than the window
    assert s.converged([10.0, 9.0, 9.0, 8.95, 8.95])  # 0.56 % over the last three: stop
    assert not s.converged([10.0, 9.0, 9.0, 8.95, 8.0])  # 11 % over the last three: go on
    assert not GASettings(16, 80, 40, 10).converged([1.0] * 40)  # no stall setting: the fixed budget


def test_ga_stops_once_converged_and_resumes_alike(tmp_path):
    """With a stall window the GA ends before its budget on a bowl it has
    solved, no worse than the fixed budget beyond the tolerance; a killed and
    resumed run stops at the same generation with the same result; without
    the setting the history is the fixed budget's, unchanged."""
    fixed = GASettings(population=16, reproduction_ratio=80, generations=60, mutation_probability=10)
    stall = GASettings(16, 80, 60, 10, stall_generations=5, stall_tol=1e-3)
    a = run_ga(SPECS, Evaluator(bowl), fixed, seed=3, progress=False)
    b = run_ga(SPECS, Evaluator(bowl), stall, seed=3, progress=False)
    n = len(b.history) - 1  # generations run
    assert 5 < n < 60 and b.evaluations < a.evaluations
    assert b.history.best.iloc[:n].tolist() == a.history.best.iloc[:n].tolist()  # same path until the stop
    best = b.history.best.tolist()
    assert best[n - 6] - best[n - 1] <= 1e-3 * best[n - 6] and best[n - 7] - best[n - 2] > 1e-3 * best[n - 7]
    assert b.best_objective < 0.05
    ck, calls = tmp_path / "ck.npz", {"n": 0}

    def dying(X):
        calls["n"] += 1
        if calls["n"] == n - 1:
            raise KeyboardInterrupt
        return bowl(X)

    with pytest.raises(KeyboardInterrupt):
        run_ga(SPECS, Evaluator(dying), stall, seed=3, checkpoint=NpzStore(ck), progress=False)
    resumed = run_ga(SPECS, Evaluator(bowl), stall, seed=3, checkpoint=NpzStore(ck), progress=False)
    assert resumed.best == b.best and resumed.history.equals(b.history)


@pytest.mark.parametrize("bad", [{"stall_generations": 0}, {"stall_generations": 2.5},
                                 {"stall_generations": 4, "stall_tol": 1.5}, {"stall_tol": "x"}])
def test_stall_settings_are_checked(bad):
    from dampertwin.errors import UserError

    with pytest.raises(UserError, match="stall_"):
        GASettings.from_config({"population": 4, "reproduction_ratio": 80, "generations": 1,
                                "mutation_probability": 10, "max_wall_s": 10, **bad})
