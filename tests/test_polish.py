"""Local polish after the GA (calibration.polish) on an analytic fit."""

from __future__ import annotations

import numpy as np
import pytest

from dampertwin.calibration.approach1 import trapezoid_weights
from dampertwin.calibration.ga import Evaluator, GASettings, ParamSpec, run_ga
from dampertwin.calibration.polish import PolishSettings, Records, polish

T = np.linspace(0, 2, 400)
TRUE = (3.0, 1.7)
MEAS = TRUE[0] * np.exp(-TRUE[1] * T) + 0.01 * np.random.default_rng(0).standard_normal(len(T))
SPECS = [ParamSpec("a", 0.5, 10.0, "log"), ParamSpec("k", 0.1, 5.0)]


def _records():
    return Records(lambda X: np.array([MEAS - x[0] * np.exp(-x[1] * T) for x in np.atleast_2d(X)]),
                   trapezoid_weights(T))


def test_trapezoid_weights_integrate_like_numpy():
    y = np.sin(T)
    assert trapezoid_weights(T) @ y == pytest.approx(np.trapezoid(y, T))


def test_polish_takes_a_short_ga_to_the_optimum_and_never_loses():
    rec = _records()
    res = run_ga(SPECS, Evaluator(rec.objective), GASettings(8, 80, 2, 10), seed=1, x0={"a": 1.0, "k": 0.5},
                 progress=False)
    j_ga = res.best_objective
    j_true = float(rec.objective(np.array([TRUE]))[0])
    assert j_ga > 1.5 * j_true  # the short GA is far from the optimum ...
    out = polish(rec, SPECS, res, PolishSettings(starts=2, max_nfev=30), progress=False)
    assert out.objective_ga == j_ga and out.polish["objective_polished"] == out.best_objective
    assert out.best_objective <= 1.02 * j_true  # ... the polish reaches it
    assert out.best["a"] == pytest.approx(TRUE[0], rel=0.02) and out.best["k"] == pytest.approx(TRUE[1], rel=0.02)
    assert len(out.polish["starts"]) == 2
    unc = {p["parameter"]: p for p in out.uncertainty["parameters"]}
    assert unc["a"]["ci95 low"] < TRUE[0] < unc["a"]["ci95 high"] and unc["a"]["determined"]


def test_polish_keeps_the_ga_result_when_it_cannot_improve():
    rec = _records()
    res = run_ga(SPECS, Evaluator(rec.objective), GASettings(8, 80, 2, 10), seed=1, x0={"a": 1.0, "k": 0.5},
                 progress=False)
    best_before, j_before = dict(res.best), res.best_objective
    out = polish(rec, SPECS, res, PolishSettings(starts=1, max_nfev=1), progress=False)  # no budget to move
    assert out.best_objective <= j_before
    if out.best_objective == j_before:
        assert out.best == pytest.approx(best_before)


def test_a_fits_own_polish_budget_overrides_the_profiles():
    """conf/profile/ci.yaml gives the valve fits their own polish budget
    (``polish.valves``); the other fits keep the profile's."""
    from omegaconf import OmegaConf

    from conftest import ROOT

    ci = OmegaConf.load(ROOT / "conf" / "profile" / "ci.yaml").polish
    assert PolishSettings.from_config(ci, "valves") == PolishSettings(starts=1, max_nfev=12)
    assert PolishSettings.from_config(ci) == PolishSettings.from_config(ci, "compliance") == PolishSettings(1, 6)
    full = OmegaConf.load(ROOT / "conf" / "profile" / "full.yaml").polish
    assert PolishSettings.from_config(full, "valves") == PolishSettings.from_config(full) == PolishSettings(3, 20)


def test_a_mistyped_polish_key_is_named_not_ignored():
    """A sub-mapping or setting the polish does not know (``valve:`` for
    ``valves:``, ``max_nfevs``) is an error naming it, not a silent default."""
    from dampertwin.errors import UserError

    for bad, name in [({"starts": 1, "max_nfev": 6, "valve": {"max_nfev": 12}}, "'valve'"),
                      ({"starts": 1, "max_nfev": 6, "max_nfevs": 4}, "'max_nfevs'"),
                      ({"starts": 1, "max_nfev": 6, "valves": {"max_nfevs": 12}}, "'valves'")]:
        with pytest.raises(UserError, match=name):
            PolishSettings.from_config(bad, "valves")
        with pytest.raises(UserError, match=name):
            PolishSettings.from_config(bad)
