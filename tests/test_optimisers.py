"""The calibration core's one entry (issue 33): ``optimisers.run(problem,
specs, settings)`` dispatches on the settings to the Gauss-Newton of the
discrepancy refits and to the concurrent GAs of approach 2, and the
problem types share one interface (``calibration.problem``). Analytic
problems, no ODE."""

import numpy as np
import pandas as pd
import pytest

from dampertwin.calibration.concurrent import BatchScorer, ConcurrentSettings, run_concurrent
from dampertwin.calibration.ga import FitResult, GASettings, ParamSpec
from dampertwin.calibration.gauss_newton import GaussNewtonSettings
from dampertwin.calibration.optimisers import run
from dampertwin.calibration.polish import Records
from dampertwin.calibration.problem import GroupedAbs, Problem, WeightedAbs, WhitenedChi2


class Linear(Problem):
    """z = A (x - truth) / noise: whitened residuals linear in the values,
    the value ``x`` as output; rows with x0 > ``cap`` are invalid."""

    def __init__(self, A, truth, cap=np.inf):
        self.A, self.truth, self.cap = np.asarray(A, float), np.asarray(truth, float), cap
        self.cost = WhitenedChi2(np.ones(len(self.A), bool))
        self.rows = 0

    def invalid(self, x):
        return "x0 above its cap" if x[0] > self.cap else None

    def evaluate(self, X):
        X = np.atleast_2d(X)
        self.rows += len(X)
        return (X - self.truth) @ self.A.T, [None] * len(X), [tuple(x) for x in X]


A = [[3.0, 1.0], [0.5, 2.0], [1.0, -1.0]]


def test_gauss_newton_recovers_a_linear_model():
    specs = [ParamSpec("a", 0.0, 10.0, start=1.0), ParamSpec("b", 1e-3, 1e1, "log", start=0.01)]
    prob = Linear(A, [7.0, 2.5])
    res = run(prob, specs, GaussNewtonSettings(iterations=40, step=1e-3))
    assert isinstance(res, FitResult)
    assert res.best["a"] == pytest.approx(7.0, rel=1e-4) and res.best["b"] == pytest.approx(2.5, rel=1e-3)
    assert res.best_objective < 1e-4 < 1.0 < res.start_objective
    assert res.simulated == pytest.approx((res.best["a"], res.best["b"]))  # the output at the fit
    assert set(res.jacobian) == {"a", "b"} and res.jacobian["a"].shape == (3,)
    assert isinstance(res.history, pd.DataFrame) and res.history["objective"].iloc[0] == res.start_objective
    assert res.evaluations == prob.rows  # one start + 2 differences, then one per iteration
    assert res.specs == specs and res.bound_hits == []


def test_gauss_newton_honours_the_prior_of_the_spec():
    """One parameter, z = 10 (u - 0.8): alone the fit ends at u = 0.8; with
    a prior at u = 0.2, sigma 0.1 in u, the objective 100 (u - 0.8)^2 +
    100 (u - 0.2)^2 has its minimum halfway, u = 0.5."""
    prob = Linear([[10.0]], [0.8])
    free = run(prob, [ParamSpec("x", 0.0, 1.0, start=0.3)], GaussNewtonSettings(iterations=60, step=1e-3))
    held = run(prob, [ParamSpec("x", 0.0, 1.0, start=0.3, prior=(0.2, 0.1))],
               GaussNewtonSettings(iterations=60, step=1e-3))
    assert free.best["x"] == pytest.approx(0.8, abs=1e-4)
    assert held.best["x"] == pytest.approx(0.5, abs=1e-3)
    assert held.best_objective == pytest.approx(100 * 0.3**2 * 2, rel=1e-3)


def test_gauss_newton_known_start_and_jacobian_cost_no_evaluation():
    """``start`` (residual, output at the start) and ``jacobian`` columns
    given: the first evaluation is the first step's; an invalid start
    difference steps the other way."""
    prob = Linear(A, [7.0, 2.5], cap=1.0 + 0.5e-3)
    specs = [ParamSpec("a", 0.0, 10.0, start=1.0), ParamSpec("b", 0.0, 10.0, start=1.0)]
    z0 = (np.array([1.0, 1.0]) - prob.truth) @ prob.A.T
    res = run(prob, specs, GaussNewtonSettings(iterations=1, step=1e-3), start=(z0, (1.0, 1.0)),
              jacobian={"b": np.asarray(A)[:, 1] * 10.0})  # dz/du = A (hi - lo)
    assert prob.rows == 1 + 1  # the difference of "a" (stepped down: up is invalid) and one step
    assert res.jacobian["a"] == pytest.approx(np.asarray(A)[:, 0] * 10.0, rel=1e-6)


def test_gauss_newton_needs_a_whitened_chi2_problem():
    rec = Records(lambda X: np.atleast_2d(X) - 1.0, np.ones(2))
    with pytest.raises(AttributeError):
        run(rec, [ParamSpec("a", 0, 2), ParamSpec("b", 0, 2)], GaussNewtonSettings(iterations=2, step=1e-3))


# ---------------------------------------------------------------- concurrent GAs behind run()
T = np.linspace(0.0, 2.0, 201)
QW = np.full(T.size, T[1] - T[0])
QW[0] = QW[-1] = (T[1] - T[0]) / 2
W = np.vstack([(T < 1.0), (T >= 1.0)]).astype(float)


class TwoPhase(Problem):
    """Residual of a signal whose first half moves with ``a``, second half with ``b``, all with ``k``."""

    def __init__(self):
        self.cost = GroupedAbs(QW, W, n_unweighted=1)
        self.measured = self.model(np.array([[1.5, -0.5, 0.7]]))[0]

    @staticmethod
    def model(X):
        a, b, k = (X[:, i:i + 1] for i in range(3))
        return (T < 1.0) * a * np.sin(3 * T) + (T >= 1.0) * b * T + k * np.cos(4 * T)

    def evaluate(self, X):
        return self.measured[None, :] - self.model(np.atleast_2d(X)), [None] * len(X)

    def scores(self, X):
        R, why = self.evaluate(X)
        return self.cost(R), why


def test_concurrent_settings_through_run_equal_the_direct_call():
    from dampertwin.calibration.concurrent import GAGroup

    groups = [GAGroup("a", (ParamSpec("a", 0.0, 3.0),)), GAGroup("b", (ParamSpec("b", -2.0, 2.0),)),
              GAGroup("compliance", (ParamSpec("k", 0.1, 2.0, "log"),))]
    ga = GASettings(population=10, reproduction_ratio=60, generations=6, mutation_probability=20)
    x0 = {"a": 1.0, "b": 0.0, "k": 1.0}
    prob = TwoPhase()
    via = run(prob, groups, ConcurrentSettings(ga), seed=3, x0=x0)
    direct = run_concurrent(groups, BatchScorer(prob.scores, 4), ga, 3, x0=x0, progress=False)
    assert isinstance(via, FitResult)
    assert via.best == direct.best and via.best_objective == direct.best_objective
    assert via.best_group_objectives == direct.best_group_objectives and set(via.best_group_objectives) == {
        "a", "b", "compliance"}
    assert via.best_evaluation == direct.best_evaluation and via.groups == ["a", "b", "compliance"]
    pd.testing.assert_frame_equal(via.history, direct.history)
    assert via.best_objective <= via.start_objective
    assert [s.key for s in via.specs] == ["a", "b", "k"] and via.records is prob


def test_problem_scores_are_the_cost_of_the_residuals_with_reasons():
    """Records (approach 1) is a Problem: eq. 6.x weighted |e| per row, NaN and a reason for a failed row."""
    w = np.array([0.5, 1.0, 0.5])

    def resid(X):
        R = np.atleast_2d(X) @ np.ones((1, 3))
        R[R[:, 0] < 0] = np.nan
        return R

    rec = Records(resid, w)
    assert isinstance(rec, Problem) and isinstance(rec.cost, WeightedAbs)
    J, why = rec.scores(np.array([[2.0], [-1.0]]))
    assert J[0] == pytest.approx(4.0) and np.isnan(J[1])
    assert why == [None, "non-finite residual"]
    np.testing.assert_array_equal(rec.weights, w)


def test_records_cost_equals_the_per_record_integrals_bit_for_bit():
    """RecordsAbs (``dampertwin fit``'s submodel problems) sums eq. 6.x record by record on each record's own
    time base exactly as the per-record integral_abs_error did: the same bits, NaN for a failed record."""
    from dampertwin.calibration.approach1 import integral_abs_error
    from dampertwin.calibration.problem import RecordsAbs

    rng = np.random.default_rng(0)
    times = [np.cumsum(rng.uniform(1e-3, 2e-3, n)) for n in (37, 101, 8)]
    meas = [rng.normal(size=len(t)) for t in times]
    sims = [rng.normal(size=(4, len(t))) for t in times]
    sims[1][2, 50] = np.nan
    R = np.hstack([m[None, :] - s for m, s in zip(meas, sims)])
    got = RecordsAbs(times)(R)
    want = np.zeros(4)
    for t, m, s in zip(times, meas, sims):
        want += np.array([integral_abs_error(t, m, row) for row in s])
    assert np.isnan(got[2]) and np.isnan(want[2])
    assert got[[0, 1, 3]].tobytes() == want[[0, 1, 3]].tobytes()
