"""Importer of own measurements: unit conversions against hand values, clean
errors naming the column, metadata with the source hash."""

import hashlib

import numpy as np
import pandas as pd
import pytest

from dampertwin.cli import main
from dampertwin.importer import MappingError, convert, import_measurement, to_si
from dampertwin.io import read_frame, read_meta


@pytest.mark.parametrize("value,unit,si,unit_si", [
    (12.5, "mm", 0.0125, "m"), (3.0, "bar", 3.0e5, "Pa"), (2.0, "kN", 2000.0, "N"), (1.0, "g", 9.80665, "m/s^2"),
    (60.0, "l/min", 1.0e-3, "m^3/s"), (20.0, "degC", 293.15, "K"), (250.0, "ms", 0.25, "s"),
    (150.0, "kPa", 1.5e5, "Pa"), (1.2, "MPa", 1.2e6, "Pa"), (4.0, "m/s^2", 4.0, "m/s^2"), (900.0, "mA", 0.9, "A"),
    (100.0, "mm/s", 0.1, "m/s"), (1.0, "psi", 6894.757293168, "Pa"), (212.0, "degF", 373.15, "K"),
    (2.0, "kip", 8896.443230521, "N"), (3.0, "in/s", 0.0762, "m/s"),
])
def test_unit_conversion_hand_values(value, unit, si, unit_si):
    x, u = to_si([value], unit)
    assert u == unit_si
    assert x[0] == pytest.approx(si, rel=1e-12)


def test_gauge_pressure_adds_atmosphere():
    x, _ = to_si([2.0], "bar", gauge=True)
    assert x[0] == pytest.approx(2e5 + 101325.0)


def test_unknown_unit_names_the_column():
    df = pd.DataFrame({"t": [0.0, 1.0], "Kraft": [1.0, 2.0]})
    m = {"columns": {"t": {"quantity": "time", "unit": "s"}, "Kraft": {"quantity": "force", "unit": "furlong"}}}
    with pytest.raises(MappingError, match=r"column 'Kraft'.*unknown unit 'furlong'"):
        convert(df, m)


def test_wrong_dimension_and_missing_column_are_named():
    df = pd.DataFrame({"t": [0.0, 1.0], "F": [1.0, 2.0]})
    with pytest.raises(MappingError, match=r"column 'F'.*'N'"):
        convert(df, {"columns": {"t": {"quantity": "time", "unit": "s"}, "F": {"quantity": "force", "unit": "bar"}}})
    with pytest.raises(MappingError, match=r"column 'X'.*not in the file"):
        convert(df, {"columns": {"X": {"quantity": "time", "unit": "s"}}})


@pytest.mark.parametrize("runs", [False, True])
def test_time_offset_keeps_integer_epoch_stamps_exact(runs):
    """Absolute microsecond stamps at 50 kHz (1.7e15 us): shifted to zero in the file's integers, then scaled;
    scaling first leaves ~0.2 us of float64 rounding (1 % of an interval)."""
    k = np.arange(4000)
    df = pd.DataFrame({"t": 1732870000123456 + 20 * k, "x": np.sin(k / 100.0)})
    m = {"columns": {"t": {"quantity": "time", "unit": "us"}, "x": {"quantity": "displacement", "unit": "m"}},
         "time_offset": True}
    if runs:
        df["r"] = np.where(k < 2000, "I1.6", "I0.9")
        m["columns"]["r"] = {"quantity": "run"}
    t = convert(df, m)["time [s]"].to_numpy()
    want = (k - np.where(k < 2000, 0, 2000)) * 2e-5 if runs else k * 2e-5
    assert np.abs(t - want).max() < 1e-12
    m["time_offset"] = False
    assert convert(df, m)["time [s]"].iloc[0] == pytest.approx(1732870000.123456)


def test_import_writes_schema_with_provenance(tmp_path):
    n = 10_000
    t_ms = np.arange(n) * 0.02  # 50 kHz (the monosine protocol's rate) in ms
    src = tmp_path / "rig.csv"
    pd.DataFrame({"Zeit": t_ms, "Weg": 5.0 * np.sin(2 * np.pi * 13 * t_ms / 1e3), "Kraft": 1.5 + 0.1 * np.cos(2 * np.pi * 13 * t_ms / 1e3),
                  "Acc": 2.0 + 0.5 * np.sin(2 * np.pi * 13 * t_ms / 1e3)}).to_csv(src, sep=";", index=False)
    mapping = tmp_path / "map.yaml"
    mapping.write_text("protocol: monosine\nrun: I1.6\ncsv: {sep: ';'}\ncolumns:\n"
                       "  Zeit: {quantity: time, unit: ms}\n  Weg: {quantity: displacement, unit: mm}\n"
                       "  Kraft: {quantity: force, unit: kN}\n  Acc: {quantity: rod acceleration, unit: g}\n"
                       "constants:\n  current: {value: 1600, unit: mA}\n")
    out = import_measurement(src, mapping, tmp_path / "own" / "monosine" / "case.parquet")
    df, meta = read_frame(out, "monosine")
    assert df["time [s]"].iloc[-1] == pytest.approx((n - 1) * 2e-5)
    assert df["displacement [m]"].abs().max() == pytest.approx(5e-3, rel=1e-3)
    assert df["force [N]"].iloc[0] == pytest.approx(1600.0)  # 1.5 + 0.1 kN at t = 0
    assert df["rod acceleration [m/s^2]"].iloc[0] == pytest.approx(2 * 9.80665)
    assert df["current [A]"].iloc[0] == pytest.approx(1.6)
    assert meta["imported"] is True and meta["synthetic"] is False
    assert meta["source_sha256"] == hashlib.sha256(src.read_bytes()).hexdigest()
    assert read_meta(out)["units"]["Kraft"] == "kN"


def test_import_of_a_json_matrix_names_its_columns(tmp_path):
    """A JSON object holding a matrix (one row per sample): columns named by
    the mapping's json: section; a mismatch is an error naming the file."""
    import json

    t = np.arange(0, 1, 1 / 512)
    src = tmp_path / "rec.json"
    src.write_text(json.dumps({"data": np.column_stack([t, np.sin(t), 2 * np.cos(t)]).tolist(), "dt": 1 / 512}))
    mapping = {"json": {"matrix": "data", "columns": ["t", "x", "F"]},
               "columns": {"t": {"quantity": "time", "unit": "s"}, "x": {"quantity": "displacement", "unit": "in"},
                           "F": {"quantity": "force", "unit": "kip"}}}
    out = import_measurement(src, mapping, tmp_path / "rec.parquet")
    df, _ = read_frame(out)
    assert df["displacement [m]"].to_numpy() == pytest.approx(0.0254 * np.sin(t))
    assert df["force [N]"].iloc[0] == pytest.approx(2 * 4448.2216152605)
    with pytest.raises(MappingError, match="rec.json.*shape"):
        import_measurement(src, {**mapping, "json": {"matrix": "data", "columns": ["t", "x"]}}, tmp_path / "b.parquet")
    with pytest.raises(MappingError, match="no key 'values'"):
        import_measurement(src, {**mapping, "json": {"matrix": "values", "columns": ["t", "x", "F"]}},
                           tmp_path / "b.parquet")


def test_import_cli_rejects_a_record_failing_the_schema(tmp_path, capsys):
    src = tmp_path / "short.csv"
    pd.DataFrame({"t": np.arange(200.0), "F": 1.0 + np.arange(200.0)}).to_csv(src, index=False)  # 1 kHz, 0.2 s
    mp = tmp_path / "m.yaml"
    mp.write_text("columns:\n  t: {quantity: time, unit: ms}\n  F: {quantity: force, unit: daN}\n")
    out = tmp_path / "monosine" / "x.parquet"
    assert main(["import", "--map", str(mp), str(src), "--out", str(out)]) == 2
    assert "missing column 'displacement [m]'" in capsys.readouterr().err and not out.exists()
    ok = tmp_path / "misc" / "x.parquet"
    assert main(["import", "--map", str(mp), str(src), "--out", str(ok)]) == 0
    assert read_frame(ok)[0]["force [N]"].tolist()[:3] == [10.0, 20.0, 30.0]
    pd.DataFrame({"t": [0.0, 1.0, 2.0], "F": [1.0, 2.0, 3.0]}).to_csv(src, index=False)  # three samples: no record
    assert main(["import", "--map", str(mp), str(src), "--out", str(tmp_path / "misc" / "y.parquet")]) == 2
    assert "3 samples over 0.002 s" in capsys.readouterr().err
