"""The active valve's own P/Q map from an active-valve bench record (calibration.active_valve_map)."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dampertwin.calibration.active_valve_map import MapRecordError, map_change, map_from_record
from dampertwin.design import load, write_map
from dampertwin.protocols import build_runs, load_protocol

CONF = Path(__file__).resolve().parents[1] / "conf"
LPM = 6.0e4  # (l/min) / (m^3/s)


def _bilinear(pq, current, dp):
    """The map's flow at ``current`` [A] (a grid current) and ``dp`` [Pa] >= 0 (linear in dp)."""
    i = int(np.argmin(np.abs(pq.currents - current)))
    return np.interp(dp, pq.dps, pq.flow[i])


def _record(pq, lag=0.0, noise=0.0, seed=0, dp_scale=1.0):
    """A bench record of the valve whose characteristic is ``pq``: the protocol's ramps, the flow lagging
    the pressure drop by ``lag`` [s] (a sluggish spool: under on the way up, over on the way down)."""
    rng = np.random.default_rng(seed)
    frames = []
    for r in build_runs(load_protocol(CONF / "test" / "activevalve.yaml")):
        ex = r.excitation
        t = ex.t0 + ex.dt * np.arange(len(ex.value))
        dp = dp_scale * ex.value
        q = _bilinear(pq, r.current, np.interp(t - lag, t, dp, left=0.0))
        frames.append(pd.DataFrame({"run": r.name, "time [s]": t, "dp [Pa]": dp,
                                    "flow [m^3/s]": q + noise / LPM * rng.standard_normal(len(t)),
                                    "current [A]": r.current}))
    return pd.concat(frames, ignore_index=True)


@pytest.fixture(scope="module")
def design():
    return load(CONF / "design" / "baseline.yaml")


def test_a_known_valve_is_recovered_through_lag_and_noise(design):
    """A record of a valve whose map is another (the alternative datasheet valve), with a 20 ms spool lag
    and 0.5 l/min of flow noise, gives that valve's map on the design's grid, not the design's map."""
    other = load(CONF / "design" / "baseline.yaml").with_overrides(
        {"active_valve.pq_map": "active_valve_alternative.csv"}).pq_map
    got = map_from_record(_record(other, lag=0.02, noise=0.5), design.pq_map, "rec")
    truth = np.array([[_bilinear(other, c, dp) for dp in design.pq_map.dps] for c in design.pq_map.currents])
    err = np.abs(got.flow - truth) * LPM
    assert err.max() < 1.5, err.max()  # l/min, on flows up to ~600 l/min; the datasheet map is far off:
    assert np.abs(design.pq_map.flow - truth).max() * LPM > 20.0
    assert np.all(np.diff(got.flow, axis=1) > 0) and np.all(np.diff(got.flow, axis=0) <= 0)
    assert np.array_equal(got.currents, design.pq_map.currents) and np.array_equal(got.dps, design.pq_map.dps)


def test_the_map_loads_into_a_design(design, tmp_path):
    """The written map passes the design's map reader (full grid, flow 0 at dp 0, monotone orderings)."""
    got = map_from_record(_record(design.pq_map, noise=2.0, seed=3), design.pq_map, "rec")
    write_map(tmp_path / "own.csv", got)
    design.dump(tmp_path / "d.yaml")
    d = load(tmp_path / "d.yaml", map_dirs=[CONF / "design"]).with_overrides({"active_valve.pq_map": "own.csv"})
    assert d.pq_map == got and d.hash() != design.hash()
    assert all(abs(v["largest_change [m^3/s]"]) * LPM < 2.0 for v in map_change(got, design.pq_map).values())


def test_a_record_short_of_the_grid_or_a_current_is_refused(design):
    short = _record(design.pq_map, dp_scale=0.8)  # reaches 128 bar; the grid goes to 150 bar
    with pytest.raises(MapRecordError, match=r"rec run 'I0.32'.*128 bar.*150 bar"):
        map_from_record(short, design.pq_map, "rec")
    rec = _record(design.pq_map)
    with pytest.raises(MapRecordError, match=r"rec: no run at the map's current 0.9 A"):
        map_from_record(rec[rec["run"] != "I0.9"], design.pq_map, "rec")


def test_the_lab_part_valve_is_measured_closer_than_its_datasheet(design):
    """On the lab's part (the truth's solenoid valve, other physics than the map): the map from its bench
    record lies within a few l/min of the valve on an ideal pressure bench (noise-free, slow ramps), where
    the datasheet map is off by tens of l/min."""
    from dampertwin.excitation import Excitation
    from dampertwin.lab import load_sample, measure_case, truth_part
    from dampertwin.truth.run import simulate

    nominal = load(CONF / "lab" / "nominal.yaml")
    sample = load_sample(CONF / "lab" / "sample.yaml")
    rec, meta = measure_case(CONF, sample, nominal, "activevalve", "baseline", 0)
    assert meta["synthetic"] is True and meta["protocol"] == "activevalve"
    got = map_from_record(rec, design.pq_map, "lab")
    p, rest = truth_part(nominal, nominal, sample)
    g = design.pq_map
    for i in (0, 4):
        t = np.linspace(0.0, 15.0, 15001)
        dp = g.dps[-1] * t / 15.0
        r = simulate(p, Excitation(0.0, float(t[1]), dp, np.gradient(dp, t), kind="pressure"), "active_valve",
                     current=float(g.currents[i]), bench={"bench_back_pressure": rest["P0"]}, rest=rest, rate=200.0)
        ideal = np.interp(g.dps, r["dp [Pa]"], r["flow [m^3/s]"])
        assert np.abs(got.flow[i] - ideal).max() * LPM < 10.0
        assert np.abs(g.flow[i] - ideal).max() * LPM > 40.0


def test_the_reader_checks_an_active_valve_record(design, tmp_path):
    """read_record on the protocol: a flipped flow sign and a current that is not its run's are refused."""
    from dampertwin.io import DataError, check_record

    rec = _record(design.pq_map, noise=0.5)
    assert len(check_record(rec, {"protocol": "activevalve"}, "rec", "activevalve", conf=CONF)) == len(rec)
    with pytest.raises(DataError, match="dp or flow sign flipped"):
        check_record(rec.assign(**{"flow [m^3/s]": -rec["flow [m^3/s]"]}), {}, "rec", "activevalve", conf=CONF)
    with pytest.raises(DataError, match="run 'I0.32'.*current"):
        check_record(rec.assign(**{"current [A]": rec["current [A]"] * 1000}), {}, "rec", "activevalve", conf=CONF)
