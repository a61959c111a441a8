"""Identifiability and uncertainty (calibration.uncertainty) on analytic
least-squares problems with known covariance."""

from __future__ import annotations

import numpy as np
import pytest

from dampertwin.calibration.uncertainty import analyse, effective_sample_size, fd_jacobian

rng = np.random.default_rng(7)
N = 400
XS = np.linspace(-0.5, 0.5, N)
P2 = XS**2 - 1 / 12  # orthogonal to 1 and x on the grid (nearly): a well-conditioned basis
A = np.column_stack([np.ones(N), XS, P2])  # y = t0 + t1 x + t2 P2(x)
THETA = np.array([1.0, -2.0, 3.0])


def _fit(y, A=A):
    th, *_ = np.linalg.lstsq(A, y, rcond=None)
    return th, y - A @ th


def test_covariance_equals_the_linear_least_squares_formula():
    sigma = 0.1
    y = A @ THETA + sigma * rng.standard_normal(N)
    th, r = _fit(y)
    u = analyse(-A, r, ["t0", "t1", "t2"], th, n_eff=N)  # residual y - A th: Jacobian -A
    expected = (r @ r) / (N - 3) * np.linalg.inv(A.T @ A)
    np.testing.assert_allclose(u.covariance, expected, rtol=1e-8, atol=1e-12 * np.abs(expected).max())
    assert u.s2 == pytest.approx(sigma**2, rel=0.2)
    assert u.table["determined"].all()


@pytest.mark.parametrize("rho, use_neff, lo, hi", [(0.0, True, 0.90, 0.99), (0.9, True, 0.85, 1.0),
                                                   (0.9, False, 0.0, 0.75)])
def test_interval_coverage_with_and_without_effective_sample_size(rho, use_neff, lo, hi):
    """95 % intervals cover the truth ~95 % of the time on white noise and,
    with the AR(1) effective sample size, on strongly autocorrelated noise;
    counting every correlated sample as independent covers far less (the
    AR(1) intervals alone: robust=False; the sandwich is checked below)."""
    hits, reps = 0, 200
    for _ in range(reps):
        e = rng.standard_normal(N)
        for i in range(1, N):
            e[i] = rho * e[i - 1] + np.sqrt(1 - rho**2) * e[i]
        th, r = _fit(A @ THETA + 0.1 * e)
        u = analyse(-A, r, ["t0", "t1", "t2"], th, n_eff=None if use_neff else N, robust=False)
        row = u.table.iloc[1]
        hits += row["ci95 low"] <= THETA[1] <= row["ci95 high"]
    assert lo <= hits / reps <= hi


def test_effective_sample_size_of_white_and_ar1_noise():
    e = rng.standard_normal(20000)
    assert effective_sample_size(e) == pytest.approx(20000, rel=0.05)
    for i in range(1, len(e)):
        e[i] = 0.9 * e[i - 1] + e[i]
    assert effective_sample_size(e) == pytest.approx(20000 * 0.1 / 1.9, rel=0.15)


def test_unidentifiable_pair_is_flagged_and_the_rest_is_not():
    """y = (t0 + t1) x + t2 P2(x): only the sum t0 + t1 is determined."""
    B = np.column_stack([XS, XS, P2])
    y = B @ THETA + 0.05 * rng.standard_normal(N)
    th = np.array([0.5, -1.5, 3.0])
    th[:2] += (np.linalg.lstsq(B[:, :1], y - B[:, 2] * 3.0, rcond=None)[0][0] - th[:2].sum()) / 2
    u = analyse(-B, y - B @ th, ["t0", "t1", "t2"], th)
    det = dict(zip(u.table["parameter"], u.table["determined"]))
    assert det == {"t0": False, "t1": False, "t2": True}
    assert "singular direction" in u.table.set_index("parameter").loc["t0", "why"]
    assert u.to_dict()["undetermined"] == ["t0", "t1"]


def test_strongly_correlated_pair_is_flagged():
    B = np.column_stack([XS, XS + 1e-3 * XS**3, np.ones(N)])
    y = B @ np.array([1.0, 1.0, 0.5]) + 1e-4 * rng.standard_normal(N)
    th, r = _fit(y, B)
    u = analyse(-B, r, ["a", "b", "c"], th).table.set_index("parameter")
    assert not u.loc["a", "determined"] and not u.loc["b", "determined"]
    assert u.loc["a", "with"] == "b" and u.loc["a", "max |corr|"] > 0.95


def test_fd_jacobian_of_a_nonlinear_residual_and_log_mapping():
    t = np.linspace(0, 2, 50)

    def res(X):  # batch (m, 2) -> (m, 50): model a exp(-k t)
        return np.array([2.0 * np.exp(-0.7 * t) - x[0] * np.exp(-x[1] * t) for x in X])

    x = np.array([2.0, 0.7])
    r, J = fd_jacobian(res, x, step=1e-7, hi=np.array([2.0 + 1e-8, 10.0]))  # first step taken backwards
    exact = np.column_stack([-np.exp(-0.7 * t), 2.0 * t * np.exp(-0.7 * t)])
    np.testing.assert_allclose(J, exact, atol=1e-5)
    assert np.allclose(r, 0)
    u = analyse(J, 0.01 * rng.standard_normal(50), ["a", "k"], np.log(x), to_value=lambda j, v: np.exp(v))
    row = u.table.iloc[0]
    assert row["value"] == pytest.approx(2.0) and row["ci95 low"] < 2.0 < row["ci95 high"]


def test_other_optima_widen_the_interval_and_mark_the_parameter():
    """y = t^2 x + noise has two optima t = +-1 with equal residuals: the
    linearised interval at t = +1 misses t = -1; other_optima stretches it
    over -1 and marks t undetermined, while an end point far outside the
    joint 95 % region (t = 0, no fit) changes nothing."""
    from dampertwin.calibration.uncertainty import other_optima

    x = np.linspace(0, 1, N)
    y = 1.0 * x + 0.05 * rng.standard_normal(N)
    t_hat = np.sqrt((x @ y) / (x @ x))  # least squares in t^2
    r = y - t_hat**2 * x
    u = analyse((-2 * t_hat * x)[:, None], r, ["t"], np.array([t_hat]), n_eff=N).to_dict()
    u["markdown"] = "# local\n"
    assert u["parameters"][0]["determined"] and u["parameters"][0]["ci95 low"] > 0
    ssr = float(r @ r)
    w = other_optima(u, [({"t": -t_hat}, ssr, 1.0), ({"t": 0.0}, float(y @ y), 9.0)])
    row = w["parameters"][0]
    assert row["ci95 low"] == pytest.approx(-t_hat) and not row["determined"]
    assert "another optimum" in row["why"] and w["undetermined"] == ["t"] and len(w["other_optima"]) == 1
    assert "Other optima" in w["markdown"]
    # only the far end point: nothing changes
    v = other_optima(u, [({"t": 0.0}, float(y @ y), 9.0)])
    assert v["parameters"][0] == u["parameters"][0] and v["other_optima"] == []


def test_sandwich_intervals_cover_a_slow_misfit_the_ar1_factor_misses():
    """y = ta a(t) + tb b(t) + white noise + a slow correlated misfit (AR(1),
    phi 0.98, what a model error looks like): the residuals' lag-1
    correlation is small, so the AR(1) interval of ta (slow regressor, 2
    cycles) is several times too narrow and covers far less than 95 %; the
    batch-means sandwich covers it, and for tb (fast regressor, which the
    slow misfit barely loads) both agree."""
    from scipy.signal import lfilter

    n, reps = 2000, 200
    t = np.arange(n)
    D = np.column_stack([np.sin(2 * np.pi * 2 * t / n), np.sin(2 * np.pi * t / 10.0)])
    theta = np.array([1.0, 1.0])
    local = np.random.default_rng(11)
    hits = {"ar1": np.zeros(2), "sandwich": np.zeros(2)}
    ratios = []
    for _ in range(reps):
        slow = lfilter([np.sqrt(1 - 0.98**2)], [1, -0.98], local.standard_normal(n))
        th, r = _fit(D @ theta + local.standard_normal(n) + 0.5 * slow, D)
        for kind, robust in (("ar1", False), ("sandwich", True)):
            tab = analyse(-D, r, ["ta", "tb"], th, robust=robust).table
            hits[kind] += (tab["ci95 low"] <= theta) & (theta <= tab["ci95 high"])
        ratios.append(tab["sandwich / AR(1)"].to_numpy())
    cov = {k: v / reps for k, v in hits.items()}
    assert cov["ar1"][0] < 0.7                       # the AR(1) factor flatters the slow parameter
    assert cov["sandwich"][0] >= 0.88                # the sandwich does not
    assert cov["sandwich"][1] >= 0.9 and cov["ar1"][1] >= 0.85
    r_med = np.median(ratios, axis=0)
    assert r_med[0] > 2.0 and r_med[1] < 1.6


def test_batches_follow_the_records():
    from dampertwin.calibration.uncertainty import batches

    b = batches(100, [70, 30], count=10)
    assert len(b) == 10 and sum(len(i) for i in b) == 100
    assert all(i.max() < 70 or i.min() >= 70 for i in b)         # no batch spans two records
    np.testing.assert_array_equal(np.concatenate(b), np.arange(100))
    with pytest.raises(ValueError, match="do not add up"):
        batches(100, [70, 20])


def test_sandwich_equals_the_least_squares_covariance_on_white_noise():
    """On independent noise and a stationary excitation (every batch sees
    the same kind of input, as a random or multi-sine test record does) the
    batch-means sandwich A^-1 S A^-1 estimates the same covariance as
    s^2 A^-1: its mean over replicates is within 10 % of sigma^2 (A^-1),
    with regressors of very different scale."""
    from dampertwin.calibration.uncertainty import batches, sandwich_covariance

    local = np.random.default_rng(5)
    D = local.standard_normal((N, 3)) * np.array([1.0, 30.0, 0.02]) + np.array([0.5, 0.0, 0.0])
    Ainv = np.linalg.inv(D.T @ D)
    groups = batches(N, [250, 150], count=10)
    mean = np.zeros((3, 3))
    for _ in range(400):
        th, r = _fit(D @ THETA + 0.3 * local.standard_normal(N), D)
        mean += sandwich_covariance(D, r, Ainv, groups) / 400
    np.testing.assert_allclose(np.diag(mean), 0.09 * np.diag(Ainv), rtol=0.1)


def test_central_jacobian_is_exact_on_cubics_and_estimates_its_error():
    """r = a^3 t + a b - 3 b^2: the Richardson-extrapolated central quotient
    is exact for a cubic, and E = J_h - J_2h = -h^2 r_aaa / 2 = -3 h^2 t for
    a, 0 for b (a curvature alone does not enter E). At a bound the column
    is one-sided of second order: error -h^2 r_aaa / 3, E = h^2 r_aaa."""
    from dampertwin.calibration.uncertainty import central_jacobian

    t = np.linspace(0, 1, 30)

    def res(X):
        return np.array([x[0] ** 3 * t + x[0] * x[1] - 3 * x[1] ** 2 for x in X])

    x = np.array([0.7, -0.4])
    exact = np.column_stack([3 * x[0] ** 2 * t + x[1], np.full_like(t, x[0] - 6 * x[1])])
    h = 1e-2
    r0, J, E = central_jacobian(res, x, h)
    np.testing.assert_allclose(r0, res(x[None, :])[0])
    np.testing.assert_allclose(J, exact, atol=1e-10)
    np.testing.assert_allclose(E, np.column_stack([-3 * h**2 * t, np.zeros_like(t)]), atol=1e-10)
    _, J1, E1 = central_jacobian(res, x, h, lo=np.array([0.69, -1.0]), hi=np.array([1.0, 1.0]))  # a near its bound
    np.testing.assert_allclose(J1[:, 0], exact[:, 0] - 2 * h**2 * t, atol=1e-10)
    np.testing.assert_allclose(E1[:, 0], 6 * h**2 * t, atol=1e-10)
    np.testing.assert_allclose(J1[:, 1], exact[:, 1], atol=1e-10)


def test_a_direction_below_the_jacobians_error_is_not_resolved():
    """y = a u + b (u + 1e-3 v): only a + b is well determined, a - b rests on
    a small singular value. A residual with solver-like jitter (a
    deterministic, rough function of the parameters, 1e-6 of the signal)
    gives finite-difference quotients whose error swamps that singular value:
    without the error estimate the pseudo-inverse turns the noise into
    narrow intervals for a and b; with it both are reported not resolved,
    while a noise-free residual keeps them finite."""
    from dampertwin.calibration.uncertainty import central_jacobian

    u = np.sin(2 * np.pi * 3 * XS)
    v = np.cos(2 * np.pi * 5 * XS)
    D = np.column_stack([u, u + 1e-3 * v])
    y = D @ np.array([1.0, 2.0]) + 0.01 * rng.standard_normal(N)
    th, _ = _fit(y, D)

    def residuals(jitter):
        def f(X):  # the jitter: a pattern drawn from the parameter values' bytes (each point its own)
            X = np.atleast_2d(X)
            rough = np.array([np.random.default_rng(list(x.view(np.uint32))).standard_normal(N) for x in X])
            return y[None, :] - X @ D.T + jitter * rough
        return f

    names = ["a", "b"]
    r0, J, E = central_jacobian(residuals(1e-6), th, 1e-4)
    noisy_flagged = analyse(J, r0, names, th, jac_error=E).table.set_index("parameter")
    noisy_blind = analyse(J, r0, names, th).table.set_index("parameter")
    r0c, Jc, Ec = central_jacobian(residuals(0.0), th, 1e-4)
    clean = analyse(Jc, r0c, names, th, jac_error=Ec).table.set_index("parameter")
    for k in names:
        assert not np.isfinite(noisy_flagged.loc[k, "ci95 high"]) and "not resolved" in noisy_flagged.loc[k, "why"]
        assert np.isfinite(noisy_blind.loc[k, "ci95 high"])          # the failure mode the floor removes
        assert np.isfinite(clean.loc[k, "ci95 high"])
    # the clean intervals are the true least-squares ones, which the blind noisy ones understate
    assert (noisy_blind.loc["a", "ci95 high"] - noisy_blind.loc["a", "ci95 low"]
            < 0.5 * (clean.loc["a", "ci95 high"] - clean.loc["a", "ci95 low"]))
