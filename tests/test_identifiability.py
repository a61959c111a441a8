"""What a fit determines where its coefficients trade off: the valve's
lift-force curve (eq. 4.19) and the top mount's dynamic stiffness with
95 % bands from the fit's (bounded) covariance."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from dampertwin.calibration.identifiability import covariance, valve_lift_force
from dampertwin.calibration.uncertainty import analyse
from dampertwin.model.valves import stiffness_force

TRUE = {"F_preload": 200.0, "a": 300.0, "b": 4000.0, "c": -200.0, "d": -15000.0}
FREE = ("a", "b", "c", "d")


def _curve(theta, x):
    v = {**TRUE, **dict(zip(FREE, theta))}
    return np.array([stiffness_force(xi, v["F_preload"], v["a"], v["b"], v["c"], v["d"]) for xi in x])


def test_lift_force_band_is_narrow_and_covers_the_truth_where_coefficients_are_undetermined():
    """Spring force measured directly at 400 lifts up to 0.15 mm (SYNTHETIC,
    2 N noise): a, b, c, d trade off (intervals beyond 100 % or |corr| near
    1) while the curve's band is a few newtons and holds the true curve."""
    rng = np.random.default_rng(4)
    x = np.linspace(0, 1.5e-4, 400)
    y = _curve([TRUE[k] for k in FREE], x) + rng.normal(0, 2.0, len(x))
    theta0 = np.array([TRUE[k] for k in FREE]) * np.array([1.2, 0.8, 0.9, 1.1])
    sol = least_squares(lambda th: _curve(th, x) - y, theta0, x_scale=np.abs(theta0), max_nfev=2000)
    h = 1e-6 * np.abs(sol.x)
    J = np.column_stack([(_curve(sol.x + e, x) - _curve(sol.x - e, x)) / (2 * hj) for e, hj in zip(np.diag(h), h)])
    u = analyse(J, sol.fun, list(FREE), sol.x, n_eff=len(x)).to_dict()
    assert u["undetermined"], u["parameters"]  # the coefficients alone are not determined
    keys, C, dof = covariance(u)
    rows = valve_lift_force({**TRUE, **dict(zip(FREE, sol.x))}, keys, C, dof, 1.5e-4)
    truth = _curve([TRUE[k] for k in FREE], [r["lift [m]"] for r in rows])
    for r, f in zip(rows, truth):
        assert r["ci95 high [N]"] - r["ci95 low [N]"] < 10.0
        assert r["ci95 low [N]"] - 1.0 <= f <= r["ci95 high [N]"] + 1.0
    # the band is the delta method of the covariance: zero covariance, zero band
    flat = valve_lift_force({**TRUE, **dict(zip(FREE, sol.x))}, keys, 0 * C, dof, 1.5e-4)
    assert all(r["ci95 low [N]"] == r["force [N]"] for r in flat)


def test_lift_force_band_scales_with_the_covariance():
    """Delta method: four times the covariance doubles the band; a parameter
    the curve does not depend on at zero lift (a) adds nothing there."""
    keys = ["a", "c", "F_preload"]
    C = np.diag([1e4, 1e4, 25.0])
    one = valve_lift_force(TRUE, keys, C, 50.0, 1.5e-4)
    four = valve_lift_force(TRUE, keys, 4 * C, 50.0, 1.5e-4)
    for r1, r4 in zip(one, four):
        w1, w4 = r1["ci95 high [N]"] - r1["force [N]"], r4["ci95 high [N]"] - r4["force [N]"]
        assert w4 == pytest.approx(2 * w1, rel=1e-12)
    no_a = valve_lift_force(TRUE, keys, np.diag([1e8, 0.0, 25.0]), 50.0, 1.5e-4)
    assert no_a[0]["ci95 high [N]"] - no_a[0]["force [N]"] == pytest.approx(one[0]["ci95 high [N]"] - one[0]["force [N]"])
    assert no_a[-1]["ci95 high [N]"] - no_a[-1]["force [N]"] > 10 * (one[-1]["ci95 high [N]"] - one[-1]["force [N]"])
