"""Fits that end on a search bound say so: the calibration core's
``bound_hits`` on every optimiser route (GA, GA + polish, least squares,
concurrent GAs), and the study report's short flag table."""

import numpy as np
import pytest

from dampertwin.calibration.ga import NEAR_BOUND, GASettings, ParamSpec, bound_hits
from dampertwin.calibration.optimisers import LeastSquaresSettings, run
from dampertwin.calibration.polish import PolishSettings, Records


def test_bound_hits_counts_in_the_parameters_own_scale():
    lin, log = ParamSpec("k", 0.0, 10.0), ParamSpec("q", 1e-3, 1e3, "log")
    inside = 10.0 * (1 - 2 * NEAR_BOUND)
    assert bound_hits([lin], {"k": inside}) == []
    (h,) = bound_hits([lin], {"k": 10.0 * (1 - NEAR_BOUND / 2)})
    assert (h["parameter"], h["bound"], h["limit"], h["kind"]) == ("k", "upper", 10.0, "search")
    # 1.1e-3 on a six-decade log interval is 0.7 % of it (lower hit); on the linear scale it would be
    # 1e-7 of the interval, and 0.01 (3 % of the decades) is not on the bound although tiny in value
    assert [h["bound"] for h in bound_hits([log], {"q": 1.1e-3})] == ["lower"]
    assert bound_hits([log], {"q": 1e-2}) == []
    assert bound_hits([lin, log], {"k": 0.0, "q": 1e3}, kind=lambda i, end: f"{i}{end}")[1]["kind"] == "11"


def _quadratic(target):
    """Residuals of x - target per parameter row (a fit whose optimum is ``target``)."""
    target = np.asarray(target, float)
    return Records(lambda X: np.atleast_2d(X) - target, np.ones(len(target)))


@pytest.mark.parametrize("route", ["ga", "ga+polish", "least squares"])
def test_every_optimiser_route_reports_an_optimum_beyond_the_interval(route):
    specs = [ParamSpec("a", 0.0, 3.0), ParamSpec("b", 0.0, 10.0)]
    inside, beyond = _quadratic([1.5, 5.0]), _quadratic([1.5, 14.0])  # b's optimum beyond its upper bound
    ga = GASettings(population=20, reproduction_ratio=80, generations=25, mutation_probability=10)
    kw = {"ga": dict(settings=ga), "ga+polish": dict(settings=ga, polish_settings=PolishSettings(starts=2, max_nfev=30)),
          "least squares": dict(settings=LeastSquaresSettings(starts=2))}[route]
    x0 = {"a": 1.0, "b": 1.0}
    assert run(inside, specs, seed=1, x0=x0, **kw).bound_hits == []
    res = run(beyond, specs, seed=1, x0=x0, **kw)
    assert [(h["parameter"], h["bound"]) for h in res.bound_hits] == [("b", "upper")]
    assert res.best["b"] >= 10.0 * (1 - NEAR_BOUND)


def test_concurrent_gas_report_their_bound_hits():
    from dampertwin.calibration.concurrent import BatchScorer, GAGroup, run_concurrent

    g1, g2 = GAGroup("one", (ParamSpec("x", 0.0, 1.0),)), GAGroup("two", (ParamSpec("y", 0.0, 1.0),))

    def scores(X):
        e = np.abs(np.atleast_2d(X) - [0.5, 2.0])  # y's optimum at 2, beyond its interval
        return np.column_stack([e[:, 0], e[:, 1], e.sum(1)])

    # x0 (the nominal design, a member of every group) on y's bound: the best any member can reach
    res = run_concurrent([g1, g2], BatchScorer(scores, 3), GASettings(20, 80, 10, 10), 3, x0={"x": 0.2, "y": 1.0},
                         progress=False)
    assert res.best["y"] == 1.0 and res.best["x"] != 0.2
    assert [(h["parameter"], h["bound"]) for h in res.bound_hits] == [("y", "upper")]


def test_report_flags_are_a_short_table():
    from dampertwin.study_report import short_flags

    kpi = [{"where": f"case {i}", "flag": "abs. diff > 25 %", "detail": "...", "worst": f"case {i}, x {v:+.2f}",
            "worst_abs": abs(v)} for i, v in enumerate([30.0, -90.0, 26.0])]
    fits = [{"where": f"valves/v{i}", "flag": "4 of 4 parameters not determined", "detail": "a, b, c, d",
             "undetermined": ["a", "b", "c", "d"] + (["F_c"] if i == 0 else []), "determined": "lift-force curve"}
            for i in range(3)]
    fits += [{"where": "valves/v1", "flag": "ends on a search bound", "detail": "d = 2 at its upper bound 2"}]
    rows = short_flags({"table 6.5": (kpi, 10), "table 6.6": ([], 10)}, fits)
    assert rows[0] == {"where": "table 6.5", "flag": "3 of 10 cases abs. diff > 25 %",
                       "detail": "worst: case 1, x -90.00; the rows are marked in the table"}
    assert {"where": "valves/v1", "flag": "ends on a search bound", "detail": "d = 2 at its upper bound 2"} in rows
    (fam,) = [r for r in rows if r["where"].startswith("valves (")]
    assert fam["where"] == "valves (3 fits)"
    assert fam["detail"].startswith("a, b, c, d in 3; F_c in 1; determined instead: lift-force curve")
    assert len(rows) == 3  # no row for a table without flags
