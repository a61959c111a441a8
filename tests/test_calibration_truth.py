"""Fits that reach the optimum, checked against the virtual laboratory's
hidden truth on the shipped lab-2 sample (conf/lab/lab2/sample.yaml) and on a second
one with other deviations and bench bandwidths 20 % off their datasheet
(conf/lab/lab2/sample2.yaml): after GA + local polish every fit ends within 1.2x
the eq. 6.x objective of the true parameters (issue 14). On lab 2 a valve's
truth is evaluated through the documented sensor chain, which is not the
lab's, so valve fits end below it (ratio 0.12-0.9); the top mount's truth
carries the lab's force-chain delay and the best zero offset (ratio ~0.88).
The stiffness-curve, preload and top-mount parameter checks are the ones
that can fail.

Slow (about 5 min on the 2-core machine): marked ``slow``; CI runs it."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from conftest import ROOT
from dampertwin.calibration.approach1 import fit_compliance, fit_top_mount, fit_valve
from dampertwin.calibration.ga import GASettings
from dampertwin.calibration.polish import PolishSettings
from dampertwin.design import load, yaml_load
from dampertwin.io import read_frame
from dampertwin.lab import generate
from dampertwin.protocols import load_protocol
from lab_truth import objective_at_truth, stiffness_curve_error, true_design, true_values

pytestmark = pytest.mark.slow

GA = GASettings(population=10, reproduction_ratio=80, generations=4, mutation_probability=10)
POLISH = PolishSettings(starts=2, max_nfev=15)
RATIO_MAX = 1.2
VALVES = ("piston_rebound", "piston_intake", "base_compression", "base_intake")


@pytest.fixture(scope="module", params=["sample.yaml", "sample2.yaml"])
def lab(request, tmp_path_factory):
    """Measured flow-bench, top-mount and compliance records of a lab sample."""
    tmp = tmp_path_factory.mktemp(request.param.split(".")[0])
    shutil.copytree(ROOT / "conf", tmp / "conf")
    shutil.copy(ROOT / "conf" / "lab" / "lab2" / request.param, tmp / "conf" / "lab" / "lab2" / "sample.yaml")
    seed = int(yaml_load((ROOT / "conf" / "config.yaml").read_text())["seed"])
    generate(tmp / "conf", tmp / "measured", seed, only=[*(("flowbench", v) for v in VALVES), ("topmount", "baseline"), ("compliance", "baseline")],
             progress=False, sample=tmp / "conf" / "lab" / "lab2" / "sample.yaml")  # the lab-2 sample: a truth with model counterparts
    return request.param, tmp / "measured"


def _report(res, sample):
    jt = objective_at_truth(res.records, res.specs, None, sample)
    tv = true_values([s.key for s in res.specs if s.key != "sensor.force_offset"], None, sample)
    print(f"{sample}: GA {res.objective_ga:.4g}, polished {res.best_objective:.4g}, truth {jt:.4g}, "
          f"ratio {res.best_objective / jt:.3f}")
    for k, v in res.best.items():
        print(f"  {k}: fitted {v:.5g}, truth {tv.get(k, float('nan')):.5g}")
    return jt, tv


@pytest.mark.parametrize("valve", VALVES)
def test_valve_fit_reaches_the_truths_objective(lab, valve):
    """Every valve of the damper: objective within 1.2x the truth's, the
    stiffness curve (what the flow bench determines; its a-b and c-d terms
    trade off) within 10 % of the real one, a shim stack's preload within 3 %
    and its bleed area within 15 %. The preload was within 2 % while the bleed
    was held at its drawing's (here: the true) value; fitted together they
    trade against this lab's bench chain, which the fit absorbs (objective
    below the truth's): sample 2's piston rebound stack +2.05 % preload,
    +6.7 % bleed (0.6 % preload with the bleed fixed, either weighting;
    bench/README.md)."""
    sample, measured = lab
    d = load(ROOT / "conf" / "design" / "baseline.yaml")
    cal = yaml_load((ROOT / "conf" / "calibration" / "valves.yaml").read_text())
    fb = load_protocol(ROOT / "conf" / "test" / "flowbench.yaml")
    meas, _ = read_frame(measured / "flowbench" / f"{valve}.parquet", "flowbench")
    res = fit_valve(d, valve, meas, cal, GA, 5, progress=False, polish_settings=POLISH,
                    bench={"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]})
    jt, tv = _report(res, sample)
    assert res.best_objective <= RATIO_MAX * jt
    assert res.best_objective <= res.objective_ga
    real, _ = true_design(None, sample)
    err = stiffness_curve_error(d.with_overrides(res.best), real, valve)
    print(f"  {valve}: stiffness curve within {100 * err:.1f} % of the real one")
    assert err <= 0.10
    # the preload the drawings get wrong is found, and the uncertainty report covers every fitted key
    if f"{valve}.F_preload" in res.best:
        assert res.best[f"{valve}.F_preload"] == pytest.approx(tv[f"{valve}.F_preload"], rel=0.03)
    if f"{valve}.A_bleed" in res.best:
        assert res.best[f"{valve}.A_bleed"] == pytest.approx(tv[f"{valve}.A_bleed"], rel=0.15)
    assert {p["parameter"] for p in res.uncertainty["parameters"]} == set(res.best)


def test_top_mount_fit_reaches_the_truths_objective_and_finds_the_force_chain(lab):
    sample, measured = lab
    d = load(ROOT / "conf" / "design" / "baseline.yaml")
    cal = yaml_load((ROOT / "conf" / "calibration" / "topmount.yaml").read_text())
    documented = load_protocol(ROOT / "conf" / "test" / "topmount.yaml")["sensors"]["force"]
    meas, _ = read_frame(measured / "topmount" / "baseline.parquet", "topmount")
    res, _, _ = fit_top_mount(d, meas, cal, GA, 5, progress=False, polish_settings=POLISH,
                              force_bandwidth=documented)
    jt, tv = _report(res, sample)
    assert res.best_objective <= RATIO_MAX * jt
    # the lab's load cell is another filter (4th-order Bessel at 1.3 kHz, 3rd-order
    # Butterworth at 800 Hz) than the documented one: its extra low-frequency delay
    assert res.best["sensor.force_delay"] == pytest.approx(tv["sensor.force_delay"], abs=30e-6)
    # a stiffness / damping is within 15 % of the real one, or the report does
    # not hide that it is not: marked undetermined (e.g. an equally good
    # optimum elsewhere, calibration.uncertainty.other_optima) with an interval
    # that covers the real one. (The intervals are statistical: within 15 %,
    # a bias they miss is allowed, e.g. k0 -9 % on lab 2 sample 1, interval
    # [1.19e6, 1.23e6] against 1.32e6; docs/validation/approach1.md "What the intervals do not cover".)
    rows = {p["parameter"]: p for p in res.uncertainty["parameters"]}
    for k in ("top_mount.k0", "top_mount.k1", "top_mount.c1"):
        r = rows[k]
        covered = r["ci95 low"] <= tv[k] <= r["ci95 high"]
        print(f"  {k}: {'determined' if r['determined'] else 'NOT determined'}, "
              f"95 % [{r['ci95 low']:.4g}, {r['ci95 high']:.4g}] ({'covers' if covered else 'misses'} "
              f"the truth {tv[k]:.4g}), fitted {100 * (res.best[k] / tv[k] - 1):+.1f} %")
        assert res.best[k] == pytest.approx(tv[k], rel=0.15) or (not r["determined"] and covered), k
    assert np.isfinite(res.uncertainty["n_eff"])


def test_compliance_fit_reaches_the_truths_objective_and_finds_the_force_chain(lab):
    """Gas content and oil bulk modulus on the damper-level sine (eq. 6.2),
    given the real valves (the valve fits are checked above): objective
    within 1.2x the truth's, the load cell's extra delay found (a delayed
    force looks like extra gas). chi and K_oil against the truth are
    printed (what the 10 mm sine determines; docs/validation/approach1.md)."""
    sample, measured = lab
    real, _ = true_design(None, sample)
    d = load(ROOT / "conf" / "design" / "baseline.yaml")
    d = d.with_overrides({f"{v}.{k}": real[f"{v}.{k}"] for v in VALVES for k in real.group(v)
                          if isinstance(real[f"{v}.{k}"], float)})
    cal = yaml_load((ROOT / "conf" / "calibration" / "compliance.yaml").read_text())
    documented = load_protocol(ROOT / "conf" / "test" / "compliance.yaml")["sensors"]["force"]
    meas, _ = read_frame(measured / "compliance" / "baseline.parquet", "compliance")
    res = fit_compliance(d, meas, cal, GASettings(population=6, reproduction_ratio=70, generations=3,
                                                  mutation_probability=8), 5, progress=False,
                         polish_settings=POLISH, force_bandwidth=documented)
    jt = objective_at_truth(res.records, res.specs, None, sample, "compliance")
    tv = true_values([s.key for s in res.specs if s.key != "sensor.force_offset"], None, sample, "compliance")
    print(f"{sample} compliance: GA {res.objective_ga:.4g}, polished {res.best_objective:.4g}, truth {jt:.4g}, "
          f"ratio {res.best_objective / jt:.3f}")
    for k, v in res.best.items():
        print(f"  {k}: fitted {v:.5g}, truth {tv.get(k, float('nan')):.5g}")
    assert res.best_objective <= RATIO_MAX * jt
    assert res.best["sensor.force_delay"] == pytest.approx(tv["sensor.force_delay"], abs=30e-6)
