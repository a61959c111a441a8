"""Dyno records (issue 38 item 3): date-time stamps in the importer, the
``dyno`` protocol's checks (any measured rate >= 100 Hz) and the KPIs of
dampertwin.dyno against analytic values of synthetic dampers."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from conftest import ROOT
from dampertwin.cli import main
from dampertwin.dyno import dyno_kpis, force_at, fv_steps, temperatures
from dampertwin.importer import MappingError, convert, import_measurement, parse_stamps
from dampertwin.io import DataError, read_meta, read_record
from dampertwin.protocols import ProtocolError, build_runs, load_protocol, validate
from dampertwin.protocols.signals import velocity_steps

T0 = pd.Timestamp("2024-05-13 14:02:11.250")


def _record(fs=300.0, A=0.025, vs=(0.05, 0.1, 0.2, 0.4), waveform="sine", c_reb=2000.0, c_comp=2000.0, cycles=5):
    """A dyno record of a linear damper (F = c v, c per direction) sampled at ``fs`` [Hz]."""
    ex = velocity_steps(A, list(vs), cycles, waveform)
    t = np.arange(0.0, ex.t_end, 1.0 / fs)
    te = ex.t0 + ex.dt * np.arange(len(ex.value))
    x, v = np.interp(t, te, ex.value), np.interp(t, te, ex.rate)
    return pd.DataFrame({"time [s]": t, "displacement [m]": x, "force [N]": np.where(v > 0, c_reb * v, c_comp * v)})


def _export(path, df, fmt="%d.%m.%Y %H:%M:%S", comma=True, temp=None, unit_mm=True):
    """``df`` as a dyno export: date-time stamps rounded to ms, force [N], displacement [mm], temperature [degC]."""
    stamps = T0 + pd.to_timedelta(np.round(df["time [s]"].to_numpy() * 1e3), unit="ms")
    sep = "," if comma else "."
    out = pd.DataFrame({"Stamp": [s.strftime(fmt) + f"{sep}{s.microsecond // 1000:03d}" for s in stamps],
                        "F": df["force [N]"], "x": df["displacement [m]"] * (1e3 if unit_mm else 1.0)})
    if temp is not None:
        out["T"] = temp
    out.to_csv(path, sep=";", index=False)
    return path


MAPPING = {"protocol": "dyno", "run": "passive", "csv": {"sep": ";"},
           "columns": {"Stamp": {"quantity": "time", "unit": "datetime"}, "F": {"quantity": "force", "unit": "N"},
                       "x": {"quantity": "displacement", "unit": "mm"}}}


# ------------------------------------------------------------ date-time stamps
@pytest.mark.parametrize("stamps", [
    ["2024-05-13 14:02:11.250", "2024-05-13 14:02:11.253", "2024-05-13 14:02:11.257"],
    ["2024-05-13T14:02:11.250", "2024-05-13T14:02:11.253", "2024-05-13T14:02:11.257"],
    ["13.05.2024 14:02:11,250", "13.05.2024 14:02:11,253", "13.05.2024 14:02:11,257"],
])
def test_date_time_stamps_become_seconds_from_the_first(stamps):
    t, info = parse_stamps(pd.Series(stamps), "col")
    assert t == pytest.approx([0.0, 0.003, 0.007], abs=1e-12)
    assert info["resolution [s]"] == pytest.approx(1e-3)


def test_a_stamp_format_from_the_mapping_and_across_midnight():
    s = pd.Series(["05/13/2024 23:59:59.998", "05/13/2024 23:59:59.999", "05/14/2024 00:00:00.000"])
    t, _ = parse_stamps(s, "col", "%m/%d/%Y %H:%M:%S.%f")
    assert t == pytest.approx([0.0, 0.001, 0.002], abs=1e-12)
    with pytest.raises(MappingError, match=r"col: 3 of 3 date-time stamps unreadable \(first '05/13/2024"):
        parse_stamps(s, "col")  # month first is not among the formats tried: a format is needed


def test_an_unreadable_stamp_is_named():
    s = pd.Series(["13.05.2024 14:02:11,250", "13.05.2024 14:02:71,253"])
    with pytest.raises(MappingError, match=r"col: 1 of 2 date-time stamps unreadable \(first '13.05.2024 14:02:71,253'\)"):
        parse_stamps(s, "col")


def test_300_hz_export_is_imported_at_its_measured_rate(tmp_path):
    df = _record(fs=300.0)
    src = _export(tmp_path / "dyno.csv", df)
    out = import_measurement(src, MAPPING, tmp_path / "dyno" / "passive.parquet")
    rec, meta = read_record(out)
    t = rec["time [s]"].to_numpy()
    assert t[0] == 0.0 and np.diff(t) == pytest.approx(1 / 300.0, rel=1e-6)  # the uniform clock, not the ms stamps
    assert meta["time stamps"]["rate [Hz]"]["passive"] == pytest.approx(300.0, rel=1e-6)
    assert meta["time stamps"]["resolution [s]"] == pytest.approx(1e-3)
    assert meta["time stamps"]["max deviation [s]"] <= 0.5e-3 + 1e-9
    assert rec["displacement [m]"].abs().max() == pytest.approx(0.025, rel=1e-3)
    assert dyno_kpis(rec)["rate [Hz]"] == pytest.approx(300.0, rel=1e-6)


def test_a_50_hz_export_is_refused(tmp_path):
    src = _export(tmp_path / "dyno.csv", _record(fs=50.0, vs=(0.05, 0.1)))
    with pytest.raises(DataError, match=r"passive.parquet \(imported from .*dyno.csv\) run 'passive': column "
                                       r"'time \[s\]': sampling rate 50 Hz .*a dyno record needs >= 100 Hz"):
        import_measurement(src, MAPPING, tmp_path / "dyno" / "passive.parquet")
    assert not (tmp_path / "dyno" / "passive.parquet").exists()


def test_a_curving_record_still_needs_its_own_rate(tmp_path):
    """The protocols with a fixed rate keep it: a 300 Hz export is no 5 kHz curving record."""
    src = _export(tmp_path / "dyno.csv", _record(fs=300.0))
    m = dict(MAPPING, protocol="curving", run="v0.05_I0.32", constants={"current": {"value": 0.32, "unit": "A"}})
    with pytest.raises(DataError, match=r"sampling rate 300 Hz; protocol curving records at 5000 Hz"):
        import_measurement(src, m, tmp_path / "curving" / "x.parquet")


@pytest.mark.parametrize("swap, what", [(False, "repeats"), (True, "is earlier than")])
def test_repeated_or_decreasing_stamps_are_refused(tmp_path, swap, what):
    src = _export(tmp_path / "dyno.csv", _record(fs=300.0))
    raw = pd.read_csv(src, sep=";")
    if swap:
        raw.loc[[100, 101], "Stamp"] = raw.loc[[101, 100], "Stamp"].to_numpy()
    else:
        raw.loc[101, "Stamp"] = raw.loc[100, "Stamp"]
    raw.to_csv(src, sep=";", index=False)
    with pytest.raises(MappingError, match=rf"dyno.csv.*column 'Stamp' run 'passive': stamp '.*' \(data row 102\) {what} the one "):
        import_measurement(src, MAPPING, tmp_path / "dyno" / "passive.parquet")


@pytest.mark.parametrize("jitter, ok", [(0.3e-3, True), (1.1e-3, False)])
def test_irregular_stamps_are_refused(tmp_path, jitter, ok):
    """Stamps in us of a logger whose samples lie off its 300 Hz clock by up to ``jitter`` [s]: accepted
    within 0.1 interval (0.33 ms; the time written is the clock), refused beyond."""
    df = _record(fs=300.0)
    src = _export(tmp_path / "dyno.csv", df)
    raw = pd.read_csv(src, sep=";")
    jit = np.random.default_rng(1).uniform(-jitter, jitter, len(df))
    stamps = T0 + pd.to_timedelta(np.round((df["time [s]"].to_numpy() + jit) * 1e6), unit="us")
    raw["Stamp"] = [s.isoformat(sep=" ") for s in stamps]
    raw.to_csv(src, sep=";", index=False)
    out = tmp_path / "dyno" / "passive.parquet"
    if ok:
        rec, _ = read_record(import_measurement(src, MAPPING, out))
        assert np.diff(rec["time [s]"].to_numpy()) == pytest.approx(1 / 300.0, rel=1e-4)
        return
    with pytest.raises(MappingError, match=r"column 'Stamp' run 'passive': irregular sampling: stamp '2024-05-13 .*' "
                                           r"\(data row \d+\) lies .* off the uniform 300 Hz clock"):
        import_measurement(src, MAPPING, out)


def test_dead_force_sensor_and_mm_under_m_are_refused(tmp_path):
    df = _record(fs=300.0)
    src = _export(tmp_path / "dyno.csv", df.assign(**{"force [N]": 12.0}))
    with pytest.raises(DataError, match=r"column 'force \[N\]' is constant \(12.0\)"):
        import_measurement(src, MAPPING, tmp_path / "dyno" / "passive.parquet")
    src = _export(tmp_path / "dyno.csv", df)
    m = {**MAPPING, "columns": {**MAPPING["columns"], "x": {"quantity": "displacement", "unit": "m"}}}
    with pytest.raises(DataError, match=r"column 'displacement \[m\]': peak 25 m .*values in mm under a \[m\] header"):
        import_measurement(src, m, tmp_path / "dyno" / "passive.parquet")


def test_temperature_column_and_the_synthetic_label(tmp_path):
    df = _record(fs=300.0, vs=(0.1, 0.2))
    temp = 25.0 + 0.1 * df["time [s]"].to_numpy()
    src = _export(tmp_path / "dyno.csv", df, temp=temp)
    m = {**MAPPING, "synthetic": True,
         "columns": {**MAPPING["columns"], "T": {"quantity": "oil temperature", "unit": "degC"}}}
    out = import_measurement(src, m, tmp_path / "dyno" / "passive.parquet")
    rec, meta = read_record(out)
    assert rec["oil temperature [K]"].iloc[0] == pytest.approx(298.15)
    assert meta["synthetic"] is True
    with pytest.raises(MappingError, match="synthetic: 'yes'; expected true or false"):
        import_measurement(src, {**m, "synthetic": "yes"}, tmp_path / "dyno" / "passive.parquet")


def test_datetime_only_for_time():
    df = pd.DataFrame({"a": ["2024-05-13 14:02:11.250"], "F": [1.0]})
    with pytest.raises(MappingError, match="column 'a': unit 'datetime'.*only applies to quantity time"):
        convert(df, {"columns": {"a": {"quantity": "force", "unit": "datetime"}}})


# ------------------------------------------------------------ protocol
def test_dyno_protocol_builds_stepped_runs():
    doc = load_protocol(ROOT / "conf" / "test" / "dyno.yaml")
    (run,) = build_runs(doc)
    assert (run.name, run.current, run.configuration) == ("passive", 0.0, "damper")
    v = run.excitation.rate
    assert np.max(np.abs(v)) == pytest.approx(max(doc["velocities"]), rel=1e-3)
    assert np.max(np.abs(run.excitation.value)) == pytest.approx(doc["amplitude"], rel=1e-6)
    active = build_runs({**doc, "currents": [0.32, 1.6], "waveform": "triangle"})
    assert [(r.name, r.current) for r in active] == [("I0.32", 0.32), ("I1.6", 1.6)]
    assert np.max(np.abs(active[0].excitation.rate)) == pytest.approx(max(doc["velocities"]))
    for bad, msg in (({"waveform": "square"}, "dyno.waveform = 'square'; expected sine or triangle"),
                     ({"cycles": 3}, "dyno.cycles = 3; a sine step needs >= 4"),
                     ({"currents": []}, "dyno.currents must be a non-empty list"),
                     ({"clicks": 3}, "dyno.clicks: unknown key")):
        with pytest.raises(ProtocolError, match=msg):
            validate({**doc, **bad}, "dyno.yaml")


# ------------------------------------------------------------ KPIs
@pytest.mark.parametrize("waveform", ["sine", "triangle"])
def test_the_protocols_runs_give_one_step_per_velocity(waveform):
    """A record of conf/test/dyno.yaml's excitation at its rate: the KPIs find each speed step, in order."""
    doc = {**load_protocol(ROOT / "conf" / "test" / "dyno.yaml"), "waveform": waveform}
    (run,) = build_runs(doc)
    ex = run.excitation
    t = np.arange(0.0, ex.t_end, 1.0 / run.rate)
    te = ex.t0 + ex.dt * np.arange(len(ex.value))
    v = np.interp(t, te, ex.rate)
    st = fv_steps(pd.DataFrame({"time [s]": t, "displacement [m]": np.interp(t, te, ex.value), "force [N]": 1e3 * v}))
    assert st["rebound velocity [m/s]"].to_numpy() == pytest.approx(doc["velocities"], rel=2e-2)
    assert st["compression force [N]"].to_numpy() == pytest.approx(-1e3 * np.array(doc["velocities"]), rel=2e-2)


@pytest.mark.parametrize("fs", [300.0, 5000.0])
@pytest.mark.parametrize("waveform", ["sine", "triangle"])
def test_fv_curve_of_a_linear_damper(fs, waveform):
    c = 2500.0
    st = fv_steps(_record(fs=fs, waveform=waveform, c_reb=c, c_comp=c))
    assert len(st) == 4
    for d in ("rebound", "compression"):
        assert st[f"{d} force [N]"].to_numpy() / st[f"{d} velocity [m/s]"].to_numpy() == pytest.approx(c, rel=1e-2)
    assert (st["rebound velocity [m/s]"] > 0).all() and (st["compression force [N]"] < 0).all()
    ref = force_at(st, [0.1, 0.2, 0.3])
    assert ref["rebound force [N]"] == pytest.approx([250.0, 500.0, 750.0], rel=1e-2)
    assert ref["compression force [N]"] == pytest.approx([-250.0, -500.0, -750.0], rel=1e-2)
    assert np.isnan(force_at(st, [2.0])["rebound force [N]"][0])  # no extrapolation


def test_fv_curve_of_an_asymmetric_damper():
    st = fv_steps(_record(fs=300.0, c_reb=3000.0, c_comp=1000.0))
    assert abs(st["rebound velocity [m/s]"]).to_numpy() == pytest.approx([0.05, 0.1, 0.2, 0.4], rel=2e-2)
    assert st["rebound force [N]"].to_numpy() / st["rebound velocity [m/s]"].to_numpy() == pytest.approx(3000.0, rel=1e-2)
    assert st["compression force [N]"].to_numpy() / st["compression velocity [m/s]"].to_numpy() == pytest.approx(1000.0, rel=1e-2)


def test_loop_area_of_a_viscous_damper():
    """Energy per cycle of F = c v at x = X sin(w t): pi c w X^2 (Den Hartog 1956, 2.8)."""
    c, X, vs = 1800.0, 0.02, (0.05, 0.1, 0.3)
    st = fv_steps(_record(fs=1000.0, A=X, vs=vs, c_reb=c, c_comp=c))
    want = [math.pi * c * (v / X) * X**2 for v in vs]  # w = v / X
    assert st["hysteresis [J]"].to_numpy() == pytest.approx(want, rel=5e-3)
    assert (st["cycles"] >= 1).all()


def test_oil_temperature_at_start_and_end():
    df = _record(fs=300.0, vs=(0.1, 0.2))
    t = df["time [s]"].to_numpy()
    df["oil temperature [K]"] = 300.0 + 0.5 * t
    got = temperatures(df)
    assert got["oil temperature start [K]"] == pytest.approx(300.0 + 0.5 * 0.5, abs=2e-3)  # mean over the first 1 s
    assert got["oil temperature end [K]"] == pytest.approx(300.0 + 0.5 * (t[-1] - 0.5), abs=2e-3)
    assert temperatures(df.drop(columns="oil temperature [K]")) == {}


def test_a_record_without_steps_is_named():
    df = _record(fs=300.0)
    df["displacement [m]"] = 0.0
    with pytest.raises(ValueError, match="the displacement is constant"):
        dyno_kpis(df)


# ------------------------------------------------------------ command line
def test_cli_import_and_kpi_of_the_shipped_example(tmp_path, capsys):
    out = tmp_path / "dyno" / "passive.parquet"
    assert main(["import", "--map", str(ROOT / "examples" / "dyno_mapping.yaml"),
                 str(ROOT / "examples" / "dyno_export.csv"), "--out", str(out)]) == 0
    assert read_meta(out)["synthetic"] is True
    capsys.readouterr()
    assert main(["kpi", "dyno", str(out), "--velocities", "0.05,0.1"]) == 0
    doc = json.loads(capsys.readouterr().out)
    k = doc["runs"]["passive"]
    assert k["rate [Hz]"] == pytest.approx(300.0, rel=1e-6) and len(k["steps"]) == 4
    # the made-up damper (scripts/make_examples.py): rebound 4000 N*s/m to 0.08 m/s, then 1200; compression
    # 2000 / 600; 20 N friction: 220 / 364 N rebound, -120 / -192 N compression at 0.05 / 0.1 m/s
    ref = k["force at reference velocities"]
    assert ref["rebound force [N]"] == pytest.approx([220.0, 364.0], rel=2e-2)
    assert ref["compression force [N]"] == pytest.approx([-120.0, -192.0], rel=2e-2)
    assert k["oil temperature end [K]"] > k["oil temperature start [K]"] > 273.15 + 23.0
    assert main(["kpi", "dyno", str(out), "--velocities", "fast"]) == 2
    assert "--velocities 'fast'" in capsys.readouterr().err


def test_kpi_refuses_more_cycles_than_a_step_has_and_an_empty_speed(tmp_path, capsys):
    """--cycles above the half-strokes a step holds would silently average all of them, the run-in one too;
    an empty item in --velocities would silently drop a speed: both exit 2 naming what was expected."""
    out = tmp_path / "passive.parquet"
    assert main(["import", "--map", str(ROOT / "examples" / "dyno_mapping.yaml"),
                 str(ROOT / "examples" / "dyno_export.csv"), "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["kpi", "dyno", str(out), "--cycles", "2"]) == 0
    capsys.readouterr()
    assert main(["kpi", "dyno", str(out), "--cycles", "1000"]) == 2
    err = capsys.readouterr().err
    assert "cycles 1000: the speed step at" in err and "half-strokes; expected at most" in err, err
    assert main(["kpi", "dyno", str(out), "--velocities", "0.1,,0.2"]) == 2
    assert "--velocities '0.1,,0.2'" in capsys.readouterr().err
