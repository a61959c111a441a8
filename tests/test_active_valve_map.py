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
    got, moved = map_from_record(_record(other, lag=0.02, noise=0.5), design.pq_map, "rec")
    truth = np.array([[_bilinear(other, c, dp) for dp in design.pq_map.dps] for c in design.pq_map.currents])
    err = np.abs(got.flow - truth) * LPM
    assert err.max() < 1.5, err.max()  # l/min, on flows up to ~600 l/min; the datasheet map is far off:
    assert np.abs(design.pq_map.flow - truth).max() * LPM > 20.0
    assert np.all(np.diff(got.flow, axis=1) > 0) and np.all(np.diff(got.flow, axis=0) <= 0)
    assert np.array_equal(got.currents, design.pq_map.currents) and np.array_equal(got.dps, design.pq_map.dps)


def test_crossing_curves_are_pooled_not_cut(design):
    """Where the 0.9 A curve runs above the 0.6 A one (it may not: more current, more restriction), the
    orderings meet both halfway (least squares), not by lowering the higher current's curve alone, and say
    how far they moved each curve."""
    pq = design.pq_map
    rec = _record(pq)
    sel = rec["run"] == "I0.9"  # the 0.9 A run passes 2 % more than the 0.6 A curve at every pressure drop
    rec.loc[sel, "flow [m^3/s]"] = 1.02 * _bilinear(pq, 0.6, rec.loc[sel, "dp [Pa]"].clip(lower=0.0))
    got, moved = map_from_record(rec, pq, "rec")
    j = np.searchsorted(pq.dps, 3.0e6)  # 30 bar
    for k in (j, len(pq.dps) - 1):
        assert got.flow[1, k] == pytest.approx(got.flow[2, k], rel=1e-9)
        assert got.flow[1, k] == pytest.approx(1.01 * pq.flow[1, k], rel=1e-6)
    assert moved[1] == pytest.approx(moved[2], rel=1e-6) == pytest.approx(0.01 * pq.flow[1, -1], rel=1e-6)
    assert moved[3] == moved[4] == 0.0


def test_the_map_loads_into_a_design(design, tmp_path):
    """The written map passes the design's map reader (full grid, flow 0 at dp 0, monotone orderings)."""
    got, _ = map_from_record(_record(design.pq_map, noise=2.0, seed=3), design.pq_map, "rec")
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
    got, moved = map_from_record(rec, design.pq_map, "lab")
    assert moved.max() * LPM < 1.0  # the orderings hardly touch the measured curves
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
    swapped = rec.copy()  # run I0.6 driven at 0.9 A
    swapped.loc[swapped["run"] == "I0.6", "current [A]"] = 0.9
    with pytest.raises(DataError, match="run 'I0.6'.*averages 0.9 A where the run label names 0.6 A"):
        check_record(swapped, {}, "rec", "activevalve", conf=CONF)


def test_the_model_and_a_lab2_part_refuse_the_bench(tmp_path):
    """The model's active valve is its map: `simulate --test activevalve` says so; a lab-2 part has no valve
    of its own: `lab --tests activevalve` says so (neither writes anything)."""
    from dampertwin.errors import UserError
    from dampertwin.lab import LabError, run_lab
    from dampertwin.simulate_test import simulate_test

    with pytest.raises(UserError, match="active valve is its P/Q map"):
        simulate_test(CONF / "design" / "baseline.yaml", "activevalve", tmp_path / "s", conf=CONF)
    with pytest.raises(LabError, match="lab-2 sample.*no solenoid valve"):
        run_lab(CONF / "lab" / "lab2" / "sample.yaml", tmp_path / "l", tests=["activevalve"], conf=CONF)
    assert not (tmp_path / "s").exists() and not (tmp_path / "l").exists()


# ------------------------------------------------------------------ dampertwin fit active-valve
def _write(tmp_path, rec, name="av.parquet"):
    from dampertwin.io import write_frame

    return write_frame(tmp_path / name, rec, {"synthetic": True, "protocol": "activevalve"})


def test_fit_active_valve_writes_a_design_with_the_part_map(design, tmp_path, capsys):
    """`dampertwin fit active-valve` on a record of another valve (20 ms spool lag, 0.5 l/min noise):
    out/design.yaml is the design with that valve's map (its no. 52 names out/map.csv, source 'measured'),
    fit.json says how far it lies from the design's map, the plot is written and nothing is flagged."""
    import json

    from dampertwin.cli import main

    other = load(CONF / "design" / "baseline.yaml").with_overrides(
        {"active_valve.pq_map": "active_valve_alternative.csv"}).pq_map
    data, out = _write(tmp_path, _record(other, lag=0.02, noise=0.5)), tmp_path / "o"
    assert main(["fit", "active-valve", "--data", str(data), "--out", str(out)]) == 0
    assert capsys.readouterr().err == ""
    fitted = load(out / "design.yaml")
    truth = np.array([[_bilinear(other, c, dp) for dp in design.pq_map.dps] for c in design.pq_map.currents])
    assert np.abs(fitted.pq_map.flow - truth).max() * LPM < 1.5
    assert fitted.param(52).value == "map.csv" and fitted.param(52).source.startswith("measured:")
    back = load(out / "design.yaml", map_dirs=[CONF / "design"]).with_overrides(
        {52: str(CONF / "design" / "active_valve_baseline.csv")})
    assert back.hash() == design.hash()  # nothing else of the design changed
    res = json.loads((out / "fit.json").read_text())
    assert res["submodel"] == "active-valve" and res["flags"] == [] and res["synthetic"] is True
    assert res["files"][str(data)]["sha256"] and (out / "pq.png").stat().st_size > 10_000
    want = map_change(fitted.pq_map, design.pq_map)
    assert {c: v["largest_change [m^3/s]"] for c, v in res["change_from_design_map"].items()} == \
        {c: v["largest_change [m^3/s]"] for c, v in want.items()}


def test_fit_active_valve_flags_crossing_curves(design, tmp_path, capsys):
    """A 0.9 A run passing 6 % more than the 0.6 A curve (a run at the wrong current?) is pooled and flagged."""
    from dampertwin.cli import main

    rec = _record(design.pq_map)
    sel = rec["run"] == "I0.9"
    rec.loc[sel, "flow [m^3/s]"] = 1.06 * _bilinear(design.pq_map, 0.6, rec.loc[sel, "dp [Pa]"].clip(lower=0.0))
    assert main(["fit", "active-valve", "--data", str(_write(tmp_path, rec)), "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert "the 0.9 A curve crosses its neighbours" in err and "the 0.6 A curve crosses" in err
    assert "0.32 A curve" not in err and "1.6 A curve" not in err


@pytest.mark.parametrize("extra, needle", [
    (["--seed", "3"], "--seed: an active-valve map is read off its bench record"),
    (["--predict", "x.parquet", "--population", "4"], "--predict, --population: an active-valve map"),
    (["--design", str(CONF / "design" / "twin_tube.yaml")], "twin_tube design has no active valve"),
])
def test_fit_active_valve_refuses_what_it_cannot_use(design, tmp_path, capsys, extra, needle):
    from dampertwin.cli import main

    data = _write(tmp_path, _record(design.pq_map))
    assert main(["fit", "active-valve", "--data", str(data), "--out", str(tmp_path / "o"), *extra]) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "o" / "fit.json").exists()


def test_fit_active_valve_refuses_a_short_record_and_writes_nothing(design, tmp_path, capsys):
    from dampertwin.cli import main

    data = _write(tmp_path, _record(design.pq_map, dp_scale=0.8))
    assert main(["fit", "active-valve", "--data", str(data), "--out", str(tmp_path / "o")]) == 2
    assert "reaches 128 bar; the design's map grid goes to 150 bar" in capsys.readouterr().err
    assert not (tmp_path / "o" / "fit.json").exists() and not (tmp_path / "o" / "design.yaml").exists()


def test_a_bench_logging_at_its_own_rate_is_read_while_it_resolves_the_grid(design, tmp_path, capsys):
    """A pressure bench logs at its own rate: 250 Hz gives the same map (quasi-static ramps, 0.16 bar between
    samples); 100 Hz (0.4 bar between samples, the grid steps 0.25 bar) and 50 Hz (below 100 Hz) are refused
    naming why; a record whose dp and flow both run negative (dp measured the other way) is refused."""
    from dampertwin.cli import main

    rec = _record(design.pq_map, noise=0.5)
    assert main(["fit", "active-valve", "--data", str(_write(tmp_path, rec.iloc[::4], "a.parquet")),
                 "--out", str(tmp_path / "a")]) == 0
    assert np.abs(load(tmp_path / "a" / "design.yaml").pq_map.flow - design.pq_map.flow).max() * LPM < 1.5
    assert main(["fit", "active-valve", "--data", str(_write(tmp_path, rec.iloc[::10], "d.parquet")),
                 "--out", str(tmp_path / "d")]) == 2
    assert "moves 4e+04 Pa between samples (median), more than the map grid's smallest step 2.5e+04 Pa" in \
        capsys.readouterr().err
    assert main(["fit", "active-valve", "--data", str(_write(tmp_path, rec.iloc[::20], "b.parquet")),
                 "--out", str(tmp_path / "b")]) == 2
    assert "sampling rate 50 Hz (measured from the time stamps); an activevalve record needs >= 100 Hz" in \
        capsys.readouterr().err
    flipped = rec.assign(**{"dp [Pa]": -rec["dp [Pa]"], "flow [m^3/s]": -rec["flow [m^3/s]"]})
    assert main(["fit", "active-valve", "--data", str(_write(tmp_path, flipped, "c.parquet")),
                 "--out", str(tmp_path / "c")]) == 2
    assert "the pressure drop is mostly negative" in capsys.readouterr().err


# ------------------------------------------------------------------ dampertwin discrepancy: the part's own map
def test_the_discrepancy_workflow_takes_the_part_map_from_its_record(design, tmp_path):
    """A measured folder with the part's active-valve record: the workflow's design gets the part's map
    (the record's valve, not the design's datasheet), says so in a note, and writes it beside its
    design.yaml; --valve-map design keeps the design's map; a passive design or no record: unchanged."""
    from dampertwin.discrepancy import entry

    other = load(CONF / "design" / "baseline.yaml").with_overrides(
        {"active_valve.pq_map": "active_valve_alternative.csv"}).pq_map
    measured = tmp_path / "measured"
    (measured / "activevalve").mkdir(parents=True)
    _write(measured / "activevalve", _record(other, noise=0.5), "baseline.parquet")
    d, note = entry.part_valve_map(design, measured, CONF)
    truth = np.array([[_bilinear(other, c, dp) for dp in design.pq_map.dps] for c in design.pq_map.currents])
    assert np.abs(d.pq_map.flow - truth).max() * LPM < 1.5 and d.hash() != design.hash()
    assert "replaced by the part's own" in note and d.param(52).value == entry.PART_MAP
    assert d.with_overrides({"geometry.M_rod": 0.9}).pq_map == d.pq_map  # variants keep the part's map
    entry._dump_design(d, tmp_path)
    assert load(tmp_path / "design.yaml").pq_map == d.pq_map
    kept, note = entry.part_valve_map(design, measured, CONF, "design")
    assert kept is design and "not used" in note
    passive = load(CONF / "design" / "twin_tube.yaml")
    assert entry.part_valve_map(passive, measured, CONF)[0] is passive
    (tmp_path / "nothing").mkdir()
    same, note = entry.part_valve_map(design, tmp_path / "nothing", CONF)
    assert same is design and "no active-valve bench record; the design's P/Q map" in note
    _write(measured / "activevalve", _record(other, noise=0.5), "part2.parquet")  # another name: said, not read
    assert "part2.parquet: not read" in entry.part_valve_map(design, measured, CONF)[1]
    (measured / ".incomplete").write_text("")  # a lab run that stopped: that, not a map error
    with pytest.raises(entry.DiscrepancyError, match="did not finish"):
        entry.part_valve_map(design, measured, CONF)


def test_a_map_that_breaks_the_map_reader_rules_is_refused(design):
    """Design.with_pq_map checks the map as the reader checks a file (orderings, flow 0 at dp 0, SI ranges)."""
    from dampertwin.design import DesignError, PQMap

    pq = design.pq_map
    rising = PQMap(pq.currents, pq.dps, pq.flow[::-1].copy())  # flow rising with the current
    with pytest.raises(DesignError, match="must not rise with current"):
        design.with_pq_map(rising, "x.csv", "test")
    with pytest.raises(DesignError, match="values in l/min"):
        design.with_pq_map(PQMap(pq.currents, pq.dps, pq.flow * 6e4), "x.csv", "test")


def test_discrepancy_cli_passes_the_part_map_to_the_workflow(design, tmp_path, monkeypatch, capsys):
    """`dampertwin discrepancy` wiring: the workflow receives the part's map and the report's note by
    default, the design's map with --valve-map design (the workflow itself stubbed: this checks the entry)."""
    from types import SimpleNamespace

    from dampertwin.cli import main
    from dampertwin.discrepancy import entry

    other = load(CONF / "design" / "baseline.yaml").with_overrides(
        {"active_valve.pq_map": "active_valve_alternative.csv"}).pq_map
    measured = tmp_path / "m"
    (measured / "activevalve").mkdir(parents=True)
    _write(measured / "activevalve", _record(other, noise=0.5), "baseline.parquet")
    seen = []
    monkeypatch.setattr(entry, "read_units", lambda measured, d, *a, **k: ([], {}, ["a note"]))
    monkeypatch.setattr(entry, "Problem", lambda *a, **k: SimpleNamespace(executor=None))
    monkeypatch.setattr(entry, "record_pool", lambda workers: None)

    def run_and_write(d, problem, cfg, profile, seed, notes, *rest):
        seen.append((d, notes))
        return {"verdict": "none", "effects": [], "gap": {"before": 1.0, "after": 1.0, "closed_fraction": 0.0}}

    monkeypatch.setattr(entry, "_run_and_write", run_and_write)
    args = ["discrepancy", "--design", str(CONF / "design" / "baseline.yaml"), "--measured", str(measured)]
    assert main([*args, "--out", str(tmp_path / "o1")]) == 0
    assert main([*args, "--out", str(tmp_path / "o2"), "--valve-map", "design"]) == 0
    (d1, n1), (d2, n2) = seen
    assert np.abs(d1.pq_map.flow - other.flow).max() * LPM < 20.0 < np.abs(d2.pq_map.flow - other.flow).max() * LPM
    assert d2.pq_map == design.pq_map and "replaced by the part's own" in n1[0] and "not used" in n2[0]
    assert n1[1:] == n2[1:] == ["a note"]
