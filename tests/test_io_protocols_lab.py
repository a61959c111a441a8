"""Data files (schema checks, atomic writes), protocols, the virtual lab."""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd
import pytest
import yaml

from dampertwin.io import DataError, read_frame, read_meta, write_frame
from dampertwin.lab import generate

from dampertwin.protocols import ProtocolError, build_runs, load_all, load_protocol, validate

from conftest import BASELINE, ROOT

CONF = ROOT / "conf"


def mono(n=10_000, fs=50_000.0, **cols):
    t = np.arange(n) / fs
    df = pd.DataFrame({"time [s]": t, "displacement [m]": 0.005 * np.sin(2 * math.pi * 13 * t),
                       "force [N]": 100 * np.sin(2 * math.pi * 13 * t), "rod acceleration [m/s^2]": -(2 * math.pi * 13) ** 2 * 0.005 * np.sin(2 * math.pi * 13 * t),
                       "current [A]": 1.6})
    for k, v in cols.items():
        df[k] = v
    return df


@pytest.fixture()
def good(tmp_path):
    return write_frame(tmp_path / "m.parquet", mono(), {"synthetic": True})


def test_round_trip_and_metadata(good):
    df, meta = read_frame(good, "monosine")
    assert meta == {"synthetic": True} and len(df) == 10_000


def _bad(tmp_path, df, suffix=".parquet"):
    p = tmp_path / f"bad{suffix}"
    if suffix == ".csv":
        df.to_csv(p, index=False)
    else:
        write_frame(p, df, {})
    return p


def rejected(path, protocol, *needles, **kw):
    with pytest.raises(DataError) as ei:
        read_frame(path, protocol, **kw)
    msg = str(ei.value)
    assert str(path) in msg
    for n in needles:
        assert n in msg, msg
    return msg


def test_reject_missing_column(tmp_path):
    rejected(_bad(tmp_path, mono().drop(columns=["rod acceleration [m/s^2]"])), "monosine",
             "missing column 'rod acceleration [m/s^2]'")


def test_reject_wrong_unit(tmp_path):
    rejected(_bad(tmp_path, mono().rename(columns={"force [N]": "force [kN]"})), "monosine",
             "'force [kN]'", "expected 'N'")


def test_reject_missing_unit(tmp_path):
    rejected(_bad(tmp_path, mono().rename(columns={"force [N]": "force"}), ".csv"), "monosine",
             "column 'force' has no unit")


def test_reject_non_monotone_time(tmp_path):
    df = mono()
    t = df["time [s]"].to_numpy().copy()
    t[500], t[501] = t[501], t[500]
    df["time [s]"] = t
    rejected(_bad(tmp_path, df), "monosine", "'time [s]'", "not increasing")


def test_reject_duplicated_time(tmp_path):
    df = mono()
    df.loc[300, "time [s]"] = df.loc[299, "time [s]"]
    rejected(_bad(tmp_path, df), "monosine", "'time [s]'", "duplicated time")


def test_reject_non_uniform_sampling(tmp_path):
    df = mono()
    df["time [s]"] = df["time [s]"] * (1 + 0.2 * (df.index > 5000))
    rejected(_bad(tmp_path, df), "monosine", "'time [s]'", "non-uniform sampling")


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_reject_nan_inf(tmp_path, bad):
    df = mono()
    df.loc[42, "force [N]"] = bad
    rejected(_bad(tmp_path, df), "monosine", "'force [N]'", "NaN/inf")


def test_reject_too_short(tmp_path):
    rejected(_bad(tmp_path, mono(n=1000)), "monosine", "needs >=")
    rejected(_bad(tmp_path, mono()), "random", "protocol random needs >= 8")


def test_reject_unknown_protocol(good):
    rejected(good, "banana", "unknown protocol 'banana'")


def test_reject_current_outside_map(tmp_path):
    rejected(_bad(tmp_path, mono(**{"current [A]": 2.5})), "monosine", "'current [A]'", "outside the active-valve map",
             current_range=(0.32, 1.6))


def test_csv_measurements_load_through_the_same_path(tmp_path):
    p = _bad(tmp_path, mono(), ".csv")
    df, meta = read_frame(p, "monosine")
    assert meta == {} and list(df.columns)[0] == "time [s]"


def test_atomic_write_leaves_no_partial_file(tmp_path, monkeypatch):
    import pyarrow.parquet as pq

    def boom(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(pq, "write_table", boom)
    with pytest.raises(KeyboardInterrupt):
        write_frame(tmp_path / "x.parquet", mono(), {})
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------ protocols
def test_all_shipped_protocols_validate_and_build():
    P = load_all(CONF / "test")
    assert set(P) == {"flowbench", "compliance", "topmount", "curving", "monosine", "random", "training",
                      "verification", "monosine16", "thermal", "friction", "module_topmount", "dyno", "activevalve"}
    runs = {k: build_runs(v, seed=5) for k, v in P.items()}
    av = runs["activevalve"]  # one pressure ramp per current of the design's map, above its largest dp (150 bar)
    assert [r.current for r in av] == [0.32, 0.6, 0.9, 1.2, 1.6] and all(r.configuration == "active_valve" for r in av)
    assert av[0].excitation.kind == "pressure" and av[0].excitation.value.max() == pytest.approx(1.6e7)
    fb = {r.bench_valve: r for r in runs["flowbench"]}
    assert fb["piston_rebound"].excitation.value.max() == pytest.approx(80 / 60000)
    assert fb["base_intake"].excitation.value.max() == pytest.approx(30 / 60000)
    assert {r.current for r in runs["curving"]} == {0.32, 0.9, 1.6}
    ms = runs["monosine"][0]
    assert ms.configuration == "module" and ms.excitation.value.max() == pytest.approx(0.005, rel=1e-3)
    rnd = runs["random"][0].excitation
    assert rnd.t_end >= 8.0
    assert not any(r.name.startswith("sweep_A0.001_f") and float(r.name.split("_f")[1]) > 20 for r in runs["topmount"])
    tr = runs["training"][0].excitation
    assert tr.value.max() == pytest.approx(0.025, rel=1e-2)
    mt = runs["module_topmount"]  # the module-level top-mount test: the training signal on the module (thesis 7.2)
    assert all(r.configuration == "module" for r in mt) and np.array_equal(mt[0].excitation.value, tr.value)
    th = runs["thermal"]
    assert {r.current for r in th} == {1.6, 0.32} and all(r.configuration == "damper" for r in th)
    assert th[0].excitation.t_end - th[0].excitation.t0 == pytest.approx(10.0)
    fr = runs["friction"]
    assert [(r.current, r.meta["precharge [Pa]"]) for r in fr] == [(0.32, 401325.0), (0.32, 1.4e6), (1.6, 401325.0),
                                                                   (1.6, 1.4e6)]
    assert all(r.configuration == "damper" and r.excitation.value.max() == pytest.approx(0.005, rel=1e-3) for r in fr)


def test_oil_temperature_column_is_checked(tmp_path):
    """The warm-up test needs the thermocouple channel in kelvin; a Celsius reading under a kelvin label
    (20-30) is refused naming the column."""
    t = np.arange(5000) / 1000.0
    df = pd.DataFrame({"time [s]": t, "displacement [m]": 0.01 * np.sin(2 * math.pi * 8 * t),
                       "force [N]": 800 * np.cos(2 * math.pi * 8 * t), "current [A]": 1.6,
                       "oil temperature [K]": 303.15 + 0.2 * t})
    assert len(read_frame(write_frame(tmp_path / "ok.parquet", df, {}), "thermal")[0]) == 5000
    rejected(_bad(tmp_path, df.drop(columns=["oil temperature [K]"])), "thermal", "missing column 'oil temperature [K]'")
    rejected(_bad(tmp_path, df.assign(**{"oil temperature [K]": 30.0 + 0.2 * t})), "thermal",
             "'oil temperature [K]'", "degrees Celsius")
    with pytest.raises(ProtocolError, match="thermal.sensors.temperature missing"):
        doc = load_protocol(CONF / "test" / "thermal.yaml")
        validate({**doc, "sensors": {"force": 1000.0}}, "thermal.yaml")


def test_precharge_column_is_checked(tmp_path):
    """The friction test needs each run's absolute gas precharge in pascal; a reading in bar (4, 14) is
    refused naming the column."""
    t = np.arange(2000) / 1000.0
    df = pd.DataFrame({"time [s]": t, "displacement [m]": 0.005 * np.sin(2 * math.pi * 1.6 * t),
                       "force [N]": 80 * np.cos(2 * math.pi * 1.6 * t) - 100, "current [A]": 0.32,
                       "precharge [Pa]": 401325.0})
    assert len(read_frame(write_frame(tmp_path / "ok.parquet", df, {}), "friction")[0]) == 2000
    rejected(_bad(tmp_path, df.drop(columns=["precharge [Pa]"])), "friction", "missing column 'precharge [Pa]'")
    rejected(_bad(tmp_path, df.assign(**{"precharge [Pa]": 4.01325})), "friction", "'precharge [Pa]'",
             "bar in a pascal column")


def test_random_signals_are_seeded():
    P = load_all(CONF / "test")["random"]
    a = build_runs(P, seed=1)[0].excitation.value
    b = build_runs(P, seed=1)[0].excitation.value
    c = build_runs(P, seed=2)[0].excitation.value
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_band_noise_has_the_requested_rms_and_band():
    P = load_all(CONF / "test")["random"]
    ex = build_runs(P, seed=3)[0].excitation
    x = ex.value
    fs = 1 / ex.dt
    f = np.fft.rfftfreq(len(x), 1 / fs)
    X = np.abs(np.fft.rfft(x)) ** 2
    assert X[f > 520].sum() < 1e-6 * X.sum()
    core = x[int(1 * fs):-int(1 * fs)]
    assert np.sqrt(np.mean(core**2)) == pytest.approx(math.hypot(1.5e-3, 3e-5), rel=0.05)


def test_bad_protocol_rejected_with_file_and_key(tmp_path):
    doc = yaml.safe_load((CONF / "test" / "monosine.yaml").read_text())
    doc["frequency"] = -13
    doc["colour"] = "red"
    p = tmp_path / "m.yaml"
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(ProtocolError) as ei:
        load_protocol(p)
    msg = str(ei.value)
    assert str(p) in msg and "monosine.frequency" in msg and "monosine.colour" in msg
    with pytest.raises(ProtocolError, match="unknown protocol"):
        validate({"protocol": "drop_test"}, "x.yaml")


# ------------------------------------------------------------ the virtual lab (more in test_lab.py)


def test_calibration_code_never_reads_the_hidden_sample():
    src = ROOT / "src" / "dampertwin"
    offenders = []
    for f in src.rglob("*.py"):
        if f.name in ("lab.py", "lab_sample.py", "lab_record.py", "lab_passive.py"):  # the lab itself
            continue
        text = f.read_text()
        if f.name == "cli.py":  # the `dampertwin lab` command is the lab's own entry point: only there
            assert text.count("from .lab import") == 2 and "def _run_lab" in text
            head, rest = text.split("def _run_lab", 1)
            text = head.replace('add_parser("lab"', "").replace('args.cmd == "lab"', "") + rest.split("\ndef ", 1)[1]
        if re.search(r"""["'/]lab["'/]|sample\.yaml|from \.+lab import|import dampertwin\.lab""", text):
            offenders.append(str(f))
    # the lab and the recovery stage (which states how far the finished fits are from the truth) read the sample;
    # no calibration stage reads what the recovery writes
    truth_readers = {"lab.py", "recovery.py", "_recovery.py"}
    for f in (ROOT / "stages").glob("*.py"):
        if f.name not in truth_readers and ("conf/lab" in f.read_text() or "dampertwin.lab" in f.read_text()):
            offenders.append(str(f))
    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
    for name, st in stages.items():
        deps = [str(d) for d in (st.get("do", st).get("deps") or [])]
        if name not in ("lab", "recovery") and any("results/recovery" in d or d.startswith("conf/lab") for d in deps):
            offenders.append(f"dvc.yaml stage {name}")
    assert offenders == []


def test_plot_command_writes_readable_pngs(tmp_path):
    """`dampertwin plot CASE` draws P-Q, F-V/F-x, mono-sine and PSD PNGs;
    without measured data it still plots the simulation."""
    from PIL import Image

    from dampertwin.cli import main

    data = tmp_path / "measured"
    generate(CONF, data, seed=3, only=[("monosine", "lower_base_intake"), ("flowbench", "base_intake_lower")],
             progress=False, workers=1)
    assert main(["plot", "lower_base_intake", "--data", str(data), "--out", str(tmp_path / "plots"),
                 "--conf", str(CONF)]) == 0
    pngs = sorted((tmp_path / "plots" / "lower_base_intake").glob("*.png"))
    assert [p.stem for p in pngs] == ["curving", "monosine", "pq", "psd"]
    for p in pngs:
        with Image.open(p) as im:
            assert im.size[0] > 600 and im.size[1] > 400
    assert main(["plot", "no_such_case", "--conf", str(CONF)]) == 2
    # a case name that is a path writes nothing outside --out
    assert main(["plot", "../variant/baseline_1.6", "--out", str(tmp_path / "o" / "p"), "--conf", str(CONF)]) == 2
    assert not (tmp_path / "o").exists()
    # a bad measured record found after the first figure: the earlier set stays whole (figures written last)
    before = {p: p.read_bytes() for p in pngs}
    import pandas as pd

    from dampertwin.io import write_frame
    write_frame(data / "monosine" / "lower_base_intake.parquet",  # readable metadata, refused by the reader
                pd.DataFrame({"time [s]": [0.0, 1.0], "force [N]": [0.0, 1.0]}), {"synthetic": True})
    assert main(["plot", "lower_base_intake", "--data", str(data), "--out", str(tmp_path / "plots"),
                 "--conf", str(CONF), "--design", str(CONF / "lab" / "nominal.yaml")]) == 2
    assert {p: p.read_bytes() for p in pngs} == before
    assert sorted(p.name for p in (tmp_path / "plots" / "lower_base_intake").iterdir()) == [p.name for p in pngs]
