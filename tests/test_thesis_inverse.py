"""scripts/thesis_inverse_core.py (issue 40 item 2, the inverse study): a
twin experiment (published numbers made by the project's own model with a
known factor; the calibration core's Gauss-Newton must recover it), the
identifiability SVD (a parameter that provably does not act on the cells is
reported undetermined), the factor / case-file rules. Fast: a few mono-sine
runs of ~20 ms."""

from __future__ import annotations

import copy
import importlib.util
import math
import sys

import numpy as np
import pytest

from conftest import ROOT
from dampertwin.design import load, yaml_load_file


def _load(name):
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


ic = _load("thesis_inverse_core")
PUB = yaml_load_file(ROOT / "conf" / "thesis" / "published.yaml")
DOC = yaml_load_file(ROOT / "conf" / "thesis" / "inverse.yaml")
PARAMS = {p.name: p for p in ic.load_params(DOC, "conf/thesis/inverse.yaml")}


def _sim(names):
    return ic.Simulator(PUB, [PARAMS[n] for n in names], DOC["maps"])


def _twin_pub(sim, cells, theta):
    """The transcription with the cells' simulated values replaced by the model's at ``theta``."""
    pub = copy.deepcopy(PUB)
    vals = sim.values(theta, cells)
    for c, v in zip(cells, vals):
        row = next(r for r in pub[ic.TABLE_KEYS[c.table]]["rows"] if r["no"] == c.no)
        row[c.column]["s"] = float(v)
    return pub


def test_twin_experiment_recovers_a_known_factor():
    """Cells of table 6.5 row 1 (13 Hz, 1.6 A) generated with the rod mass x 1.2;
    the inverse fit from the nominal 1.0 must land on 1.2 and fit the cells."""
    names = ["rod_mass"]
    sim = _sim(names)
    cells = ic.cells_of(PUB, tables=("6.5",), cases={"baseline_1.6"})
    truth = {"rod_mass": 1.2}
    twin = _twin_pub(sim, cells, truth)
    cells = ic.cells_of(twin, tables=("6.5",), cases={"baseline_1.6"})
    sim = ic.Simulator(twin, [PARAMS[n] for n in names], DOC["maps"])
    mask = np.ones(len(cells), bool)
    z0, S = ic.jacobian(lambda th: ic.scaled_residual(cells, sim.values(th, cells)), sim.params, {}, 0.05)
    assert np.linalg.norm(z0) > 0.5, "the start must be visibly off the twin data"
    pr = ic.make_problem(sim, cells, mask)
    res = ic.fit(pr, sim.params, names, {}, ic.to_u_columns(S, sim.params, names), (z0, None), 15, 0.05, 1e-5)
    assert res.best["rod_mass"] == pytest.approx(1.2, rel=5e-3)
    assert res.best_objective < 1e-3 < res.start_objective


def test_identifiability_reports_a_parameter_without_effect_as_undetermined():
    """The random test's tail level cannot act on mono-sine cells: its column
    is zero, its share of the determined subspace 0, it is not selected; the
    rod mass is."""
    names = ["rod_mass", "noise_tail"]
    sim = _sim(names)
    cells = ic.cells_of(PUB, tables=("6.5",), cases={"baseline_1.6", "baseline_0.32"})
    _, S = ic.jacobian(lambda th: ic.scaled_residual(cells, sim.values(th, cells)), sim.params, {}, 0.05)
    idn = ic.identifiability(S, sim.params, 1.0)
    by = {r["parameter"]: r for r in idn["parameters"]}
    assert by["noise_tail"]["column norm"] == 0.0
    assert by["noise_tail"]["determined share"] == pytest.approx(0.0, abs=1e-12)
    assert idn["selected"] == ["rod_mass"] and idn["rank"] == 1
    assert by["rod_mass"]["determined share"] == pytest.approx(1.0, abs=1e-9)


def test_identifiability_of_collinear_columns_is_one_direction():
    """Two parameters acting identically are one determined direction (their
    sum), the difference undetermined; each has share 1/2; one is selected."""
    ps = [ic.FactorParam("a", ("x",), 0.5, 2.0), ic.FactorParam("b", ("y",), 0.5, 2.0),
          ic.FactorParam("c", ("z",), 0.5, 2.0)]
    col = np.array([3.0, -1.0, 2.0, 0.5])
    S = np.column_stack([col, col, np.zeros(4)]) / ps[0].half_log_range
    idn = ic.identifiability(S, ps, 1.0)
    assert idn["rank"] == 1 and len(idn["selected"]) == 1 and idn["selected"][0] in ("a", "b")
    share = {r["parameter"]: r["determined share"] for r in idn["parameters"]}
    assert share["a"] == pytest.approx(0.5) and share["b"] == pytest.approx(0.5) and share["c"] == 0.0
    assert idn["singular values"][0] == pytest.approx(math.sqrt(2) * np.linalg.norm(col))


def test_factors_scale_baseline_and_case_values_and_keep_published_ones():
    base = load(ROOT / "conf" / "design" / "baseline.yaml")
    ps = [PARAMS["pi_stiffness"], PARAMS["precharge"], PARAMS["tm_static"]]
    th = {"pi_stiffness": 1.2, "precharge": 1.25, "tm_static": 0.8}
    lower = yaml_load_file(ROOT / "conf" / "variant" / "lower_piston_intake.yaml")["overrides"]
    o = ic.case_overrides(base, lower, ps, th)
    assert o["piston_intake.a"] == pytest.approx(1.2 * lower["piston_intake.a"])  # the case keeps its ratio
    assert o["piston_intake.c"] == pytest.approx(1.2 * lower["piston_intake.c"])
    assert o["oil.P_0"] == pytest.approx(101325.0 + 1.25 * (base["oil.P_0"] - 101325.0))  # gauge pressure scaled
    assert o["top_mount.F_LD"] == pytest.approx([0.8 * x for x in base["top_mount.F_LD"]])
    pre = yaml_load_file(ROOT / "conf" / "variant" / "increased_precharge.yaml")["overrides"]
    assert ic.case_overrides(base, pre, ps, th)["oil.P_0"] == pre["oil.P_0"]  # published 5 bar: fixed
    assert ic.case_overrides(base, {}, ps, {}) == {}


def test_map_and_spectrum_factors_and_bad_config():
    coef = DOC["maps"]["active_valve_baseline.csv"]
    c = ic.map_coefficients(coef, [PARAMS["av_gain"]], {"av_gain": 2.0})
    assert c["gain"] == 2.0 * coef["gain"] and c["dp_open_hi"] == coef["dp_open_hi"]
    proto = {"bands": [{"band": [1, 25], "rms": 1e-3}, {"band": [25, 500], "rms": 3e-5}]}
    p = ic.random_protocol(proto, [PARAMS["noise_tail"]], {"noise_tail": 2.0})
    assert p["bands"][1]["rms"] == 6e-5 and p["bands"][0]["rms"] == 1e-3 and proto["bands"][1]["rms"] == 3e-5
    with pytest.raises(ValueError, match="inv.yaml.*expected 0 < lo < 1 < hi"):
        ic.load_params({"parameters": [{"name": "x", "keys": ["geometry.M_rod"], "lo": 1.1, "hi": 2}]}, "inv.yaml")
    with pytest.raises(ValueError, match="inv.yaml: parameters: empty or missing"):
        ic.load_params({}, "inv.yaml")
    with pytest.raises(ValueError, match="do not reproduce"):
        ic.check_maps(load(ROOT / "conf" / "design" / "baseline.yaml"),
                      {"active_valve_baseline.csv": {**coef, "gain": 1e-9}})


def test_scaled_residual_is_one_at_the_targets_edge():
    """z = (thesis - project) / tolerance: 15 % of |thesis| for a peak, 2 dB for a
    PSD level, so |z| <= 1 is the comparison page's 'agrees'."""
    cells = [ic.Cell("6.5", 1, "baseline_1.6", "compression", -10.0), ic.Cell("6.6", 1, "baseline_1.6", "f200", -5.0)]
    z = ic.scaled_residual(cells, [-8.5, -7.0])
    assert z == pytest.approx([-1.0, 1.0])
    for v in ([-8.4, -7.1], [-8.6, -6.9], [-12.0, -2.0]):
        z = ic.scaled_residual(cells, v)
        agree = [ic.tc.agrees(d, c.unit) for c, d in zip(cells, ic.diffs(cells, v))]
        assert list(np.abs(z) <= 1.0) == agree


def test_kpi_jumps_flag_sign_flips_of_peaks_only():
    """A step that flips a peak's sign is a jump of the literal KPI; the same
    change on a PSD cell (dB, any sign) is a slope."""
    ps = [ic.FactorParam("a", ("x",), 0.5, 2.0), ic.FactorParam("b", ("y",), 0.5, 2.0)]
    cells = [ic.Cell("6.5", 1, "baseline_1.6", "rebound", 2.0), ic.Cell("6.6", 1, "baseline_1.6", "f200", -5.0)]
    values = [0.1, -5.0]
    # z = (thesis - v) / sigma; a step h = 0.05 changes v by -sigma * S * h
    S = np.array([[10.0 / (0.3 * 0.05), 0.01], [-100.0, 0.0]])  # a: v 0.1 -> -9.9 (flip); b: tiny
    J = ic.kpi_jumps(cells, values, S, ps, {}, 0.05)
    assert J.tolist() == [[True, False], [False, False]]
    assert ic.fd_steps(ps, {"a": 2.0}, 0.05).tolist() == [-0.05, 0.05]  # at the upper bound: the other way
