"""Time-resolved grouped Sobol indices (calibration.sensitivity, issue 12)."""

import numpy as np
import pytest

from dampertwin.calibration import sensitivity as sens
from dampertwin.calibration.ga import ParamSpec
from dampertwin.errors import UserError


def _groups():
    return [sens.Group("a", (ParamSpec("a.x1", -np.pi, np.pi), ParamSpec("a.x2", -np.pi, np.pi))),
            sens.Group("b", (ParamSpec("b.x3", -np.pi, np.pi),)),
            sens.Group("c", (ParamSpec("c.x4", 0.0, 1.0), ParamSpec("c.x5", 1.0, 10.0, "log")))]


def _model(X, t):
    """Time-varying output: group a drives it alone early (t < 0.3), group b
    alone late (t > 0.7), a mix in between; group c never matters; one
    instant (t = 0) has no output variance at all."""
    x1, x2, x3 = X[:, 0:1], X[:, 1:2], X[:, 2:3]
    early = (t < 0.3).astype(float)[None, :]
    late = (t > 0.7).astype(float)[None, :]
    mid = 1 - early - late
    y = early * (np.sin(x1) + 0.5 * x2) + late * x3 ** 2 + mid * (np.sin(x1) + 2 * np.sin(x3) + 0.3 * x1 * x3)
    y[:, 0] = 1.234
    return y


def test_design_size_is_the_thesis_320_runs():
    groups = [sens.Group(f"g{i}", (ParamSpec(f"g{i}.p", 0.0, 1.0),)) for i in range(4)]
    G, X = sens.sample(groups, 32, seed=7)
    assert sens.runs_needed(32, 4) == 320 == len(X) == len(G)
    assert np.all((G >= 0) & (G <= 1))
    G2, _ = sens.sample(groups, 32, seed=7)
    assert np.array_equal(G, G2)  # seeded: same config, same numbers


def test_estimator_equals_salib_at_sampled_instants():
    from SALib.analyze import sobol

    groups = _groups()
    _, X = sens.sample(groups, 64, seed=11)
    t = np.linspace(0, 1, 401)
    Y = _model(X, t)
    S1, conf, masked = sens.first_order(Y, len(groups), seed=5, num_resamples=50)
    problem = sens.salib_problem(groups)
    assert masked[0] and not masked[1:].any()
    for k in (1, 37, 120, 200, 251, 333, 400):
        ref = sobol.analyze(problem, Y[:, k], calc_second_order=True, num_resamples=50, seed=5)
        np.testing.assert_allclose(S1[:, k], ref["S1"], rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(conf[:, k], ref["S1_conf"], rtol=1e-8, atol=1e-12)


def test_estimator_without_second_order_equals_salib():
    from SALib.analyze import sobol

    groups = _groups()
    _, X = sens.sample(groups, 32, seed=3, second_order=False)
    assert len(X) == sens.runs_needed(32, 3, second_order=False)
    t = np.linspace(0, 1, 50)
    Y = _model(X, t)
    S1, _, _ = sens.first_order(Y, 3, second_order=False, seed=2, num_resamples=10)
    ref = sobol.analyze(sens.salib_problem(groups), Y[:, 40], calc_second_order=False, num_resamples=10, seed=2)
    np.testing.assert_allclose(S1[:, 40], ref["S1"], rtol=1e-10)


def test_analytic_function_null_and_sole_driver_groups():
    groups = _groups()
    t = np.linspace(0, 1, 201)
    res, Y = sens.run(groups, lambda X: _model(X, t), 512, seed=1, num_resamples=30)
    early, late = (t > 0) & (t < 0.3), t > 0.7
    a, b, c = res.S1
    assert np.all(np.abs(c[~res.masked]) < 0.05)  # group c cannot affect the output: ~0
    assert np.all(np.abs(a[early] - 1) < 0.05) and np.all(np.abs(b[late] - 1) < 0.05)  # sole drivers: ~1
    assert np.all(np.abs(b[early]) < 0.05) and np.all(np.abs(a[late]) < 0.05)
    assert np.isnan(res.S1[:, 0]).all() and res.meta["masked_instants"] == 1
    W = sens.result_weights(res, t, sens.WeightSettings(smooth_s=0.02, normalise="max"))
    assert W.shape == res.S1.shape and np.all(W >= 0) and np.allclose(W.max(axis=1)[:2], 1.0)
    Wr = sens.result_weights(res, t, sens.WeightSettings())
    assert np.all(Wr[:, 0] == 0)
    df = res.to_frame(t)
    assert len(df) == 3 * len(t) and {"time [s]", "group", "S1 [-]", "S1 lower [-]", "masked"} <= set(df.columns)


def test_weighted_integrals_eq_7_1():
    t = np.linspace(0, 2, 2001)
    w = np.full(len(t), t[1] - t[0])
    w[0] = w[-1] = w[0] / 2
    W = np.vstack([np.ones_like(t), (t < 1).astype(float)])
    r = np.vstack([np.ones_like(t), 2 * np.ones_like(t)])
    J = sens.weighted_integrals(np.abs(r), w, W)
    np.testing.assert_allclose(J[:, 0], [2.0, 4.0], rtol=1e-12)
    np.testing.assert_allclose(J[:, 1], [1.0005, 2.001], rtol=1e-3)


def test_bad_settings_name_the_key():
    with pytest.raises(UserError, match="normalise"):
        sens.WeightSettings.from_config({"normalise": "median"})
    with pytest.raises(UserError, match="power of 2"):
        sens.sample(_groups(), 30, seed=1)
    with pytest.raises(UserError, match="unknown key"):
        sens.WeightSettings.from_config({"smoothing": 1})
    with pytest.raises(UserError, match="weights.rule"):
        sens.WeightSettings.from_config({"rule": "upper"})
    with pytest.raises(ValueError, match="needs the confidence"):
        sens.weights(np.ones((1, 3)), np.arange(3.0), sens.WeightSettings())
    with pytest.raises(UserError, match="n_max = 48"):
        sens.run_converged(_groups(), lambda X: X, 16, 48, 0.1, 1, lambda r: r.S1)
    with pytest.raises(UserError, match="n_max = 8"):
        sens.run_converged(_groups(), lambda X: X, 16, 8, 0.1, 1, lambda r: r.S1)


def test_failed_runs_drop_their_base_sample_block():
    groups = _groups()
    t = np.linspace(0, 1, 101)

    def out(X):
        Y = _model(X, t)
        Y[[3, 50], 10:] = np.nan  # two failed simulations, in base samples 0 and 6 (blocks of 2G + 2 = 8 runs)
        return Y

    res, Y = sens.run(groups, out, 64, seed=1, num_resamples=10)
    assert res.meta["failed_runs"] == 2 and res.meta["dropped_base_samples"] == 2
    assert Y.shape[0] == (64 - 2) * 8 and np.all(np.isfinite(Y))
    ref, _ = sens.run(groups, lambda X: _model(X, t), 64, seed=1, num_resamples=10)
    early = (t > 0) & (t < 0.3)
    assert np.allclose(res.S1[0, early], ref.S1[0, early], atol=0.1)  # still the same answer
    with pytest.raises(UserError, match="at least 2"):
        sens.run(groups, lambda X: np.full((len(X), 5), np.nan), 4, seed=1)


def test_salib_design_of_2n_starts_with_the_design_of_n():
    """The property the convergence loop's reuse rests on: SALib's Saltelli
    design of 2N (same seed, scrambled Sobol', no skip) begins with the N
    design's rows, both designs; another seed does not."""
    groups = _groups()
    for second_order in (False, True):
        for n in (4, 16, 32):
            assert sens.is_prefix(groups, n, seed=9, second_order=second_order)
            _, X = sens.sample(groups, n, 9, second_order)
            _, X2 = sens.sample(groups, 2 * n, 9, second_order)
            assert np.array_equal(X2[:len(X)], X) and len(X2) == 2 * len(X)
    _, X = sens.sample(groups, 8, 9)
    _, Xo = sens.sample(groups, 16, 10)
    assert not np.array_equal(Xo[:len(X)], X)


def test_convergence_loop_reuses_runs_and_stops_at_tol_or_cap():
    groups = _groups()
    t = np.linspace(0, 1, 101)
    evaluated = []

    def out(X):
        evaluated.append(len(X))
        return _model(X, t)

    weigh = lambda r: sens.result_weights(r, t, sens.WeightSettings())  # noqa: E731
    # a tolerance nothing reaches: runs to the cap, not converged, each run simulated once
    res, Y, rec = sens.run_converged(groups, out, 8, 64, 1e-9, 3, weigh, num_resamples=20)
    assert rec["n_sequence"] == [8, 16, 32, 64] and rec["converged"] is False and rec["n_final"] == 64
    assert evaluated == [sens.runs_needed(8, 3)] + [sens.runs_needed(n, 3) for n in (8, 16, 32)]
    assert rec["runs_simulated"] == sum(evaluated) == sens.runs_needed(64, 3) == len(Y)
    assert len(rec["change_per_doubling"]) == 3 and all(c > 0 for c in rec["change_per_doubling"])
    ref, Yref = sens.run(groups, lambda X: _model(X, t), 64, 3, num_resamples=20)
    np.testing.assert_array_equal(Y, Yref)  # the reused rows are the rows of the 64 design
    np.testing.assert_array_equal(res.S1, ref.S1)
    # a loose tolerance: stops at the first doubling, converged
    evaluated.clear()
    res, Y, rec = sens.run_converged(groups, out, 8, 64, 10.0, 3, weigh, num_resamples=20)
    assert rec["n_sequence"] == [8, 16] and rec["converged"] is True and res.meta["n_base"] == 16
    assert evaluated == [sens.runs_needed(8, 3), sens.runs_needed(8, 3)]
    # n_max = n_base: no check
    _, _, rec = sens.run_converged(groups, out, 8, 8, 0.1, 3, weigh, num_resamples=20)
    assert rec["converged"] is None and rec["n_sequence"] == [8] and rec["change_per_doubling"] == []


def test_weight_change_metric():
    live = np.array([True, True, True, False])
    W_old = np.array([[1.0, 0.5, 0.0, 9.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 0.4, 0.0, 0.0],
                      [0.2, 0.2, 0.0, 0.0]])
    W_new = np.array([[1.0, 0.0, 0.5, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0],
                      [1.0, 1.0, 0.0, 5.0]])
    # group 0: a third of the weight moved from the 2nd to the 3rd instant (the masked last instant ignored);
    # group 1: no weight either side; group 2: weight from none; group 3: all weight lost; group 4: rescaled only
    np.testing.assert_allclose(sens.weight_change(W_new, W_old, live), [1 / 3, 0.0, 1.0, 1.0, 0.0], atol=1e-15)


def test_lower_bound_weights_ignore_undetermined_instants_and_favour_sharp_ones():
    t = np.arange(4.0)
    S1 = np.array([[0.3, 0.3, 0.3, 0.6]])
    conf = np.array([[0.4, 0.2, 0.05, 0.05]])
    W = sens.weights(S1, t, sens.WeightSettings(normalise="none"), conf)
    assert W[0, 0] == 0.0  # the interval [-0.1, 0.7] covers 0: no weight
    assert 0 < W[0, 1] < W[0, 2] < W[0, 3]  # same estimate, narrower band -> more weight
    np.testing.assert_allclose(W[0], [0.0, 0.1, 0.25, 0.55])
    We = sens.weights(S1, t, sens.WeightSettings(normalise="none", rule="estimate"))
    np.testing.assert_allclose(We[0], S1[0])  # the thesis as written: the estimate, band ignored
    # smoothing keeps the zeros exact away from any weight (a running sum leaves ~1e-16 behind otherwise)
    tl = np.arange(20000) * 2e-4
    S = np.zeros((1, len(tl)))
    S[0, 100:200] = np.random.default_rng(0).uniform(0.2, 0.9, 100)
    Ws = sens.weights(S, tl, sens.WeightSettings(smooth_s=0.002), np.zeros_like(S))
    assert np.all(Ws[0, 300:] == 0) and Ws[0, 150] > 0
    # a group whose interval covers 0 everywhere has no weight left: flagged (its GA could not select)
    W2 = sens.weights(np.vstack([S1, S1]), t, sens.WeightSettings(), np.vstack([conf, np.full(4, 0.7)]))
    assert not W2[1].any() and sens.unweighted_groups(["sharp", "vague"], W2) == ["vague"]
    # on an analysed design (N = 32): where group a drives the output alone (early) it keeps its largest
    # weights; where its share is not established it loses them, where the estimate alone would keep some
    tt = np.linspace(0, 1, 201)
    res, _ = sens.run(_groups(), lambda X: _model(X, tt), 32, seed=1, num_resamples=50)
    live = ~res.masked
    Wl = sens.result_weights(res, tt, sens.WeightSettings(normalise="none"))
    We = sens.weights(res.S1, tt, sens.WeightSettings(normalise="none", rule="estimate"))
    early = live & (tt < 0.3)
    assert np.all(Wl[0, early] > 0.3) and Wl[0, early].min() >= Wl[0, live & ~early].max()
    assert np.all(Wl <= We + 1e-12)
    assert np.mean(Wl[0, live] == 0) > np.mean(We[0, live] == 0) + 0.2
