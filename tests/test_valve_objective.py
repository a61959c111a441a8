"""The flow-bench objective's weighting (conf/calibration/valves.yaml
``objective``): eq. 6.1 as printed or its relative form, and the checks of
its config. Records are SYNTHETIC (the baseline's own valve model)."""

import numpy as np
import pandas as pd
import pytest

from conftest import BASELINE, ROOT
from dampertwin.calibration.approach1 import fit_valve, valve_objective, valve_objective_name
from dampertwin.calibration.ga import GASettings
from dampertwin.design import load, yaml_load_file
from dampertwin.errors import UserError
from dampertwin.excitation import Excitation
from dampertwin.protocols import load_protocol
from dampertwin.simulation import simulate

VALVE = "piston_rebound"


@pytest.fixture(scope="module")
def bench_record():
    """A flow-bench ramp 0 -> 80 -> 0 l/min over 4 s of the baseline's piston rebound valve (SYNTHETIC)."""
    d = load(BASELINE)
    fb = load_protocol(ROOT / "conf" / "test" / "flowbench.yaml")
    bench = {"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]}
    t = np.arange(0, 4.001, 1e-3)
    q = 80.0 / 60000.0 * np.interp(t, [0, 2.0, 4.001], [0.0, 1.0, 0.0])
    f = simulate(d, Excitation.from_samples(t, q, kind="flow"), "valve", bench_valve=VALVE, rate=1000.0,
                 bench=bench).to_frame()
    dp = (f["p upstream [Pa]"] - f["p downstream [Pa]"]).to_numpy()[: len(t)]
    return d, bench, pd.DataFrame({"time [s]": t, "flow [m^3/s]": q, "dp [Pa]": dp, "run": VALVE})


def _objective(d, bench, meas, objective, overrides) -> float:
    """The objective of the design ``d`` + ``overrides`` on the record (fit_valve's start objective)."""
    cal = {"shim": [{"name": "a", "window": [0.9, 1.1]}], "input_cutoff": 20.0}
    if objective is not None:
        cal["objective"] = objective
    res = fit_valve(d.with_overrides(overrides), VALVE, meas, cal, GASettings(2, 50, 1, 10, max_wall_s=120), 1,
                    bench=bench, progress=False)
    return res.start_objective


def test_relative_weighting_counts_the_low_flow_end(bench_record):
    """A bleed half its area errs only at low flow (a few bar); a spring 10 %
    stiffer errs over the whole opened range. Eq. 6.1 (pascal-seconds) ranks
    the bleed error as the smaller one; the relative weighting ranks it as
    the larger (in relative terms it is: 2x at low flow against <= 10 %)."""
    d, bench, meas = bench_record
    bleed = {f"{VALVE}.A_bleed": 0.5 * d[f"{VALVE}.A_bleed"]}
    spring = {f"{VALVE}.a": 1.1 * d[f"{VALVE}.a"]}
    absolute = {"weighting": "absolute"}
    relative = {"weighting": "relative", "dp_floor": 1.0e5}
    assert _objective(d, bench, meas, absolute, bleed) < _objective(d, bench, meas, absolute, spring)
    assert _objective(d, bench, meas, relative, bleed) > 1.5 * _objective(d, bench, meas, relative, spring)
    # the absent mapping is eq. 6.1 as printed
    assert _objective(d, bench, meas, None, bleed) == _objective(d, bench, meas, absolute, bleed)


def test_relative_objective_with_a_floor_above_every_pressure_is_eq_6_1_scaled(bench_record):
    """Limit case: when dp_floor exceeds every |dp_test| the weights are
    1 / dp_floor everywhere, so the relative objective is eq. 6.1 / dp_floor."""
    d, bench, meas = bench_record
    floor = 1.0e9
    assert meas["dp [Pa]"].abs().max() < floor
    spring = {f"{VALVE}.a": 1.1 * d[f"{VALVE}.a"]}
    j_abs = _objective(d, bench, meas, {"weighting": "absolute"}, spring)
    j_rel = _objective(d, bench, meas, {"weighting": "relative", "dp_floor": floor}, spring)
    assert j_rel == pytest.approx(j_abs / floor, rel=1e-12)


def test_objective_config_is_checked_and_named():
    assert valve_objective({}) == ("absolute", 0.0)
    assert valve_objective({"objective": {"weighting": "relative", "dp_floor": 2e4}}) == ("relative", 2e4)
    for bad, word in [({"weighting": "log"}, "weighting"), ({"weighting": "relative"}, "dp_floor"),
                      ({"weighting": "relative", "dp_floor": -1.0}, "dp_floor"),
                      ({"weighting": "relative", "dp_floor": float("nan")}, "dp_floor"),
                      ({"weighting": "relative", "dp_floor": True}, "dp_floor"),
                      ({"weighting": "relative", "dp_flor": 1e5}, "dp_floor"), ("relative", "mapping")]:
        with pytest.raises(UserError, match=word) as e:
            valve_objective({"objective": bad}, where="my.yaml")
        assert "my.yaml" in str(e.value)
    assert valve_objective_name({})[1] == "Pa*s"
    assert valve_objective_name({"objective": {"weighting": "relative", "dp_floor": 1e5}})[1] == "s"


def test_shipped_valve_config_fits_the_bleed_relatively():
    """The study's flow-bench fits (and `dampertwin fit valve`'s default) weigh
    relatively and fit the shim stacks' bleed inside a window around the drawing."""
    cal = yaml_load_file(ROOT / "conf" / "calibration" / "valves.yaml")
    assert valve_objective(cal)[0] == "relative"
    assert "A_bleed" in [it["name"] for it in cal["shim"]]
