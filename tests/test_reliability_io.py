"""Issue 35, reliability of fit, import, lab and every output folder: one
measurement reader with the same checks everywhere, command-line options
range-checked before any work, output folders checked and locked, upper
physical limits, same input -> same bytes. Each test fails when its check is
removed (the mutations are listed in the issue's report)."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from dampertwin.cli import main
from dampertwin.design import DesignError, load
from dampertwin.errors import UserError
from dampertwin.importer import MappingError, import_measurement
from dampertwin.io import DataError, read_record, write_frame
from dampertwin.io.outdir import OutputError, check_out_dir, lock_path, out_lock

from conftest import BASELINE, ROOT

CONF = ROOT / "conf"
FUZZ = int(os.environ.get("FUZZ_EXAMPLES", 40))


# ------------------------------------------------------------------ records (SYNTHETIC)
def mono(fs=50_000.0, T=0.2, A=0.005, run="I1.6"):
    """A plausible monosine record: 13 Hz, 5 mm, a dissipative force (c v + k x)."""
    t = np.arange(int(round(T * fs)) + 1) / fs
    w = 2 * math.pi * 13.0
    x, v = A * np.sin(w * t), A * w * np.cos(w * t)
    return pd.DataFrame({"time [s]": t, "displacement [m]": x, "force [N]": 2000.0 * v + 1e4 * x,
                         "rod acceleration [m/s^2]": -A * w * w * np.sin(w * t), "current [A]": 1.6, "run": run})


def flow(valve="piston_rebound", fs=1000.0):
    """A plausible flow-bench record: triangle flow to 80 l/min, dp ~ q^2."""
    t = np.arange(int(12 * fs) + 1) / fs
    q = 1.3333e-3 * np.interp(np.mod(t, 4.0), [0, 2, 4], [0, 1, 0])
    return pd.DataFrame({"time [s]": t, "flow [m^3/s]": q, "dp [Pa]": 3e6 * (q / 1.3333e-3) ** 2 + 1e3, "run": valve})


def fric(fs=1000.0):
    """A friction-test record (protocol friction: precharge column, P..bar_I.. labels)."""
    t = np.arange(int(0.96 * fs) + 1) / fs
    w = 2 * math.pi * 0.05 / 0.005
    x = 0.005 * np.sin(w * t)
    return pd.DataFrame({"time [s]": t, "displacement [m]": x, "force [N]": 100 * np.tanh(np.cos(w * t) * 50),
                         "current [A]": 0.32, "precharge [Pa]": 401325.0, "run": "P4.01bar_I0.32"})


def refused(tmp: Path, df: pd.DataFrame, test, *needles, name="m.parquet", meta=None, **kw) -> str:
    p = tmp / name
    if p.suffix == ".csv":
        df.to_csv(p, index=False)
    else:
        write_frame(p, df, meta or {})
    with pytest.raises(DataError) as ei:
        read_record(p, test, conf=CONF, **kw)
    msg = str(ei.value)
    assert str(p) in msg, msg
    for n in needles:
        assert n in msg, msg
    return msg


def _scaled(df, col, k):
    df = df.copy()
    df[col] = df[col] * k
    return df


def test_plausible_records_pass(tmp_path):
    for df, test, name in ((mono(), "monosine", "a.parquet"), (flow(), "flowbench", "piston_rebound.parquet"),
                           (fric(), "friction", "f.parquet")):
        read_record(write_frame(tmp_path / name, df, {}), test, conf=CONF)


READER_CASES = {
    "dead displacement": (lambda: mono().assign(**{"displacement [m]": 0.001}), "monosine", "'displacement [m]' is constant"),
    "all-zero force": (lambda: mono().assign(**{"force [N]": 0.0}), "monosine", "'force [N]' is constant (0.0)"),
    "mm under [m]": (lambda: _scaled(mono(), "displacement [m]", 1e3), "monosine", "values in mm under a [m] header"),
    "cm under [m]": (lambda: _scaled(mono(), "displacement [m]", 1e2), "monosine",  # 0.5 m: physical, 100x the protocol's
                     "is 100x the protocol's 0.005 m"),
    "ms under [s]": (lambda: _scaled(mono(), "time [s]", 1e3), "monosine", "time in ms under a [s] header"),
    "0.1 s record": (lambda: mono(T=0.1), "monosine", "record lasts 0.1 s"),
    "flipped force": (lambda: _scaled(mono(), "force [N]", -1.0), "monosine", "force sign flipped"),
    "500 Hz decimated": (lambda: mono().iloc[::100].reset_index(drop=True), "monosine", "sampling rate 500 Hz"),
    "time stretched 2.4 %": (lambda: _scaled(mono(), "time [s]", 1.024), "monosine", "protocol monosine records at"),
    "reversed time": (lambda: mono().assign(**{"time [s]": mono()["time [s]"].to_numpy()[::-1]}), "monosine",
                      "reversed time axis"),
    "no run column": (lambda: mono().drop(columns="run"), "monosine", "no 'run' column"),
    "l/min under [m^3/s]": (lambda: _scaled(flow(), "flow [m^3/s]", 60_000.0), "flowbench",
                            "values in l/min under a [m^3/s] header"),
    "bar under [Pa]": (lambda: _scaled(flow(), "dp [Pa]", 1e-5), "flowbench", "values in bar under a [Pa] header"),
    "flipped dp": (lambda: _scaled(flow(), "dp [Pa]", -1.0), "flowbench", "sign flipped"),
    "compliance as top mount": (lambda: mono(fs=5000.0, run="v0.4_I1.6").drop(columns=["rod acceleration [m/s^2]"]),
                                "topmount", "is not a run of"),
    "friction as top mount": (fric, "topmount", "'P4.01bar_I0.32' is not a run of"),
    "run of another valve": (lambda: flow("base_intake"), "flowbench", "named after valve design piston_rebound"),
}


@pytest.mark.parametrize("case", READER_CASES, ids=list(READER_CASES))
def test_reader_refuses_each_class_naming_file_and_column(tmp_path, case):
    make, test, needle = READER_CASES[case]
    refused(tmp_path, make(), test, needle, name="piston_rebound.parquet" if test == "flowbench" else "m.parquet")


def test_reader_checks_the_valve_asked_for_and_the_metadata_protocol(tmp_path):
    p = write_frame(tmp_path / "rec.parquet", flow("base_intake"), {})
    with pytest.raises(DataError, match="expected a record of valve 'piston_rebound'"):
        read_record(p, "flowbench", conf=CONF, valve="piston_rebound")
    refused(tmp_path, mono(), "random", "metadata says protocol 'monosine'", meta={"protocol": "monosine"})


def test_header_only_csv_is_named_empty(tmp_path):
    p = tmp_path / "h.csv"
    p.write_text("time [s],displacement [m],force [N],current [A],run\n")
    with pytest.raises(DataError, match="empty record: no rows"):
        read_record(p, "compliance", conf=CONF)


def test_size_limit_refuses_before_parsing(tmp_path, monkeypatch):
    p = tmp_path / "junk.csv"
    p.write_bytes(b"x,y\n" + b"1,2\n" * 300_000)  # 1.2 MB
    monkeypatch.setenv("DAMPERTWIN_MAX_FILE_MB", "1")
    with pytest.raises(DataError, match=r"larger than the 1 MB limit"):
        read_record(p, "monosine", conf=CONF)


def test_generic_record_one_hz_time_base_and_flipped_sign(tmp_path):
    """fit friction on a device record without protocol: ms written as s, a flipped force."""
    df = fric().drop(columns=["run", "precharge [Pa]", "current [A]"])
    refused(tmp_path, _scaled(df, "time [s]", 1e3), None, "time in ms (or us) under a [s] header")
    refused(tmp_path, _scaled(df, "force [N]", -1.0), None, "force sign flipped")
    refused(tmp_path, _scaled(df, "displacement [m]", 1e3), None, "mm under a [m] header")


# ------------------------------------------------------------------ fit / import through the CLI
def _cli(*argv):
    return subprocess.run([sys.executable, "-m", "dampertwin.cli", *argv], cwd=ROOT, capture_output=True, text=True,
                          env=dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT / "src")), timeout=300)


@pytest.mark.parametrize("argv, needle", [
    (["--population", "0"], "--population 0"), (["--population", "1"], "--population 1"),
    (["--generations", "-3"], "--generations -3"), (["--generations", "0"], "--generations 0"),
    (["--seed", "-1"], "--seed -1"), (["--current", "nan"], "--current nan"),
    (["--current", "99"], "--current 99.0: outside the active-valve map"),
    (["--valve", "piston_rebond"], "--valve 'piston_rebond': expected one of piston_rebound"),
])
def test_fit_arguments_are_range_checked_before_any_work(tmp_path, capsys, argv, needle):
    out = tmp_path / "o"
    code = main(["fit", "compliance", "--data", str(tmp_path / "missing.parquet"), "--out", str(out), *argv])
    err = capsys.readouterr().err
    assert code == 2 and needle in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists() and not lock_path(out).exists()


def test_fit_bounds_file_with_a_duplicate_key_is_one_line(tmp_path, capsys):
    b = tmp_path / "b.yaml"
    b.write_text("parameters:\n  - {name: F_c, bounds: [0, 1]}\nparameters: []\n")
    assert main(["fit", "friction", "--data", "x.parquet", "--bounds", str(b), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "b.yaml: not valid YAML: line 3" in err and "duplicate key 'parameters'" in err and "Traceback" not in err


@pytest.mark.parametrize("submodel", ["topmount", "valve", "compliance"])
def test_fit_refuses_a_record_of_another_test(tmp_path, capsys, submodel):
    """A friction record (metadata protocol friction) given to another submodel's fit, before any work."""
    rec = write_frame(tmp_path / "fr.parquet", fric(), {"protocol": "friction", "synthetic": True})
    out = tmp_path / "o"
    assert main(["fit", submodel, "--valve", "piston_rebound", "--data", str(rec), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"a friction record (its metadata); a {submodel} fit reads" in err and not out.exists(), err


@pytest.mark.parametrize("cmd", [["lab", "--sample", "conf/lab/sample.yaml"],
                                 ["discrepancy", "--design", "d.yaml", "--measured", "m"]])
@pytest.mark.parametrize("opt", [["--workers", "0"], ["--seed", "-5"]])
def test_workers_and_seed_checked_in_every_command(tmp_path, capsys, cmd, opt):
    assert main([*cmd, "--out", str(tmp_path / "o"), *opt]) == 2
    err = capsys.readouterr().err
    assert opt[0] in err and "Traceback" not in err, err


@pytest.mark.parametrize("cmd", [["fit", "friction", "--data", "x.parquet"], ["lab", "--sample", "s.yaml"],
                                 ["discrepancy", "--design", "d.yaml", "--measured", "m"],
                                 ["import", "x.csv", "--map", "m.yaml"]])
def test_output_that_is_not_a_folder_or_not_writable_is_refused_first(tmp_path, capsys, cmd):
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    out = blocker / "sub" / ("o.parquet" if cmd[0] == "import" else "o")
    assert main([*cmd, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "is a file, not a folder" in err and "Traceback" not in err, err
    if cmd[0] != "import":
        assert main([*cmd, "--out", str(blocker)]) == 2
        assert "exists and is not a folder" in capsys.readouterr().err


def test_read_only_output_folder_is_refused(tmp_path):
    if os.access("/proc/sys", os.W_OK):
        pytest.skip("no read-only folder available")
    with pytest.raises(OutputError, match="not writable"):
        check_out_dir("/proc/sys/dampertwin_out")


def test_second_run_on_the_same_output_is_refused_and_the_lock_removed(tmp_path):
    out = tmp_path / "o"
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        lock_path(out).parent.mkdir(parents=True, exist_ok=True)
        lock_path(out).write_text(f"{sleeper.pid}\n")  # a live run holds OUT
        with pytest.raises(OutputError, match=f"another dampertwin run \\(process {sleeper.pid}\\)"):
            with out_lock(out):
                pass
    finally:
        sleeper.kill()
        sleeper.wait()
    with out_lock(out) as lock:  # its process gone: the stale lock is taken over ...
        assert lock.read_text().split() == [str(os.getpid()), os.path.realpath(out)]
    assert not lock.exists()  # ... and removed at the end
    assert list(tmp_path.iterdir()) == []  # nothing created beside OUT
    with pytest.raises(ZeroDivisionError):
        with out_lock(out):
            1 / 0
    assert not lock_path(out).exists()  # removed on failure too


def test_discrepancy_failure_while_swapping_leaves_no_old_folder(tmp_path, monkeypatch):
    from dampertwin.discrepancy import entry

    out = tmp_path / "res"
    out.mkdir()
    (out / "verdict.json").write_text("{}")  # an earlier output
    monkeypatch.setattr(entry, "run", lambda *a, **k: {"design": None})
    monkeypatch.setattr(entry, "verdict_document", lambda res: {})
    monkeypatch.setattr(entry, "_dump_design", lambda d, folder: None)
    monkeypatch.setattr("dampertwin.discrepancy.report.write_report", lambda *a, **k: None)
    real = os.replace

    def failing(a, b):
        if Path(b) == out and ".tmp" in Path(a).name:
            raise OSError(28, "No space left on device")
        return real(a, b)

    monkeypatch.setattr(entry.os, "replace", failing)
    with pytest.raises(OSError):
        entry._run_and_write(None, None, {}, "ci", 0, [], "d.yaml", "m", out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"], list(tmp_path.iterdir())
    assert (out / "verdict.json").read_text() == "{}"  # the earlier output is back


def _import_src(tmp, t_unit_factor=1e3, n=10_001, stretch=1.0, dp=False):
    t = np.arange(n) / 50_000.0 * stretch
    w = 2 * math.pi * 13.0
    x = 5.0 * np.sin(w * t)
    src = tmp / "rig.csv"
    pd.DataFrame({"t": t * t_unit_factor, "x": x, "F": 2.0 * np.cos(w * t) + 0.01 * x,
                  "a": -0.5 * np.sin(w * t)}).to_csv(src, index=False)
    return src


MAP = {"protocol": "monosine", "run": "I1.6",
       "columns": {"t": {"quantity": "time", "unit": "ms"}, "x": {"quantity": "displacement", "unit": "mm"},
                   "F": {"quantity": "force", "unit": "kN"}, "a": {"quantity": "rod acceleration", "unit": "g"}},
       "constants": {"current": {"value": 1.6, "unit": "A"}}}


def test_import_refuses_time_base_and_rate_errors_before_writing(tmp_path):
    out = tmp_path / "monosine" / "c.parquet"
    import_measurement(_import_src(tmp_path), MAP, out)  # the plausible record imports
    before = out.read_bytes()
    ms_as_s = {**MAP, "columns": {**MAP["columns"], "t": {"quantity": "time", "unit": "s"}}}
    with pytest.raises(DataError, match="time in ms under a"):
        import_measurement(_import_src(tmp_path), ms_as_s, out)
    with pytest.raises(DataError, match="sampling rate 48828.1 Hz; protocol monosine records at 50000 Hz"):
        import_measurement(_import_src(tmp_path, stretch=1.024), MAP, out)
    assert out.read_bytes() == before  # a refused import leaves the earlier file untouched
    no_proto = {k: v for k, v in ms_as_s.items() if k != "protocol"}
    with pytest.raises(DataError, match="time in ms \\(or us\\) under a \\[s\\] header"):
        import_measurement(_import_src(tmp_path), no_proto, tmp_path / "misc" / "c.parquet")
    assert not (tmp_path / "misc" / "c.parquet").exists()


def test_import_mapping_duplicate_key_and_unknown_quantity(tmp_path, capsys):
    src = _import_src(tmp_path)
    mp = tmp_path / "m.yaml"
    mp.write_text("columns:\n  t: {quantity: time, unit: ms}\n  t: {quantity: time, unit: s}\n")
    with pytest.raises(MappingError, match=r"m.yaml: not valid YAML: line \d+.*duplicate"):
        import_measurement(src, mp, tmp_path / "o.parquet")
    bad = {**MAP, "columns": {**MAP["columns"], "F": {"quantity": "forse", "unit": "kN"}}}
    with pytest.raises(MappingError, match="unknown quantity 'forse'"):
        import_measurement(src, bad, tmp_path / "monosine" / "o.parquet")
    assert isinstance(MappingError("x"), UserError)


# ------------------------------------------------------------------ design, lab, variants
@pytest.mark.parametrize("key, value, needle", [
    ("geometry.M_rod", 1e300, "no. 1 (geometry.M_rod): value 1e+300; expected > 0 and <= 50 kg"),
    ("geometry.D_PT", 5.0, "no. 2 (geometry.D_PT): value 5.0; expected > 0 and <= 0.3 m"),
    ("piston_rebound.A_slot", 0.5, "piston_rebound.A_slot): value 0.5; expected > 0 and <= 0.01 m^2"),
    ("oil.P_0", 1e12, "(oil.P_0): value 1000000000000.0; expected > 0 and <= 1e+08 Pa"),
    ("geometry.V_b", 3.0, "(geometry.V_b): value 3.0"),
])
def test_upper_physical_limits_of_the_design(key, value, needle):
    with pytest.raises(DesignError) as ei:
        load(BASELINE).with_overrides({key: value}, source="big.yaml")
    assert needle in str(ei.value) and "big.yaml" in str(ei.value), str(ei.value)


@pytest.mark.parametrize("where, corner", [("dp [Pa]", 5000.0), ("force [N]", 1e9)])
def test_lab_sensor_corner_above_nyquist_is_refused(where, corner):
    from dampertwin.lab import LabError, check_corners, load_sample
    from dampertwin.protocols import load_all

    protocols = load_all(CONF / "test")
    s = load_sample(CONF / "lab" / "sample.yaml")
    check_corners(s, protocols)  # the shipped sample passes
    s["benches"]["sensors"][where]["corner"] = corner
    with pytest.raises(LabError, match=re.escape(f"sample.yaml: benches.sensors.{where}.corner: {corner:g} Hz above the "
                                                 "Nyquist frequency")):
        check_corners(s, protocols)


def test_lab_channel_described_twice_is_refused(tmp_path):
    import yaml

    from dampertwin.lab import LabError, load_sample

    doc = yaml.safe_load((CONF / "lab" / "sample.yaml").read_text())
    doc["benches"]["bandwidth"] = {"flow [m^3/s]": 1e9}  # the sensors section would silently win
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(LabError, match=re.escape("benches.bandwidth.flow [m^3/s] and benches.sensors.flow [m^3/s] both")):
        load_sample(tmp_path / "s.yaml")


def _variant_cfg(**kw):
    doc = {"case": "x", "row": 1, "title": "t", "current": 1.6, "overrides": {}}
    doc.update(kw)
    return OmegaConf.create({"variant": {k: v for k, v in doc.items() if v is not None}, "seed": 1})


@pytest.mark.parametrize("kw, needle", [({"row": -1}, "row -1; expected an integer 1..10"),
                                        ({"row": 11}, "row 11"),
                                        ({"current": None, "curent": 1.6}, "unknown key 'curent' (did you mean 'current'?)")])
def test_sweep_variant_keys_and_row_named_with_the_file(tmp_path, kw, needle):
    from dampertwin.sweep import check_job

    with pytest.raises(UserError) as ei:
        check_job(_variant_cfg(**kw), tmp_path)
    assert needle in str(ei.value) and str(tmp_path / "conf" / "variant" / "x.yaml") in str(ei.value), str(ei.value)
    cfg = _variant_cfg()
    cfg.seed = -1
    with pytest.raises(UserError, match="seed=-1"):
        check_job(cfg, tmp_path)


@pytest.mark.parametrize("kw, needle", [({"tests": "monosine"}, "tests='monosine': expected a list of tests"),
                                        ({"tests": ["monosine", "nosuch"]}, "expected a list of tests of conf/test/"),
                                        ({"level": 0.2}, "level=0.2 without factor=")])
def test_sweep_tests_and_a_level_without_factor_are_refused_before_any_work(kw, needle):
    """`tests=monosine` (a string, read letter by letter before) and a level that would be ignored."""
    from dampertwin.sweep import check_job

    cfg = _variant_cfg()
    cfg.tests = ["monosine", "random"]
    check_job(cfg, ROOT)  # the plain job passes
    for k, v in kw.items():
        cfg[k] = v
    with pytest.raises(UserError, match=re.escape(needle)):
        check_job(cfg, ROOT)


# ------------------------------------------------------------------ same input, same bytes
def test_staged_outputs_carry_no_temporary_name():
    sys.path.insert(0, str(ROOT / "stages"))
    try:
        from _common import final_name
    finally:
        sys.path.pop(0)
    assert final_name(Path("/r/.valves_x.tmpab12_9")) == "valves_x" and final_name(Path("/r/valves_x")) == "valves_x"


def test_import_and_fit_are_byte_identical_on_rerun(tmp_path):
    src = _import_src(tmp_path)
    a, b = tmp_path / "a" / "monosine" / "c.parquet", tmp_path / "b" / "monosine" / "c.parquet"
    import_measurement(src, MAP, a)
    import_measurement(src, MAP, b)
    assert a.read_bytes() == b.read_bytes()
    rec = write_frame(tmp_path / "f.parquet", fric(), {"synthetic": True})
    docs = []
    for o in ("f1", "f2"):
        assert main(["fit", "friction", "--data", str(rec), "--out", str(tmp_path / o), "--param", "F_c=0:300",
                     "--param", "F_s=0:400"]) == 0
        docs.append((tmp_path / o / "fit.json").read_bytes())
    assert docs[0] == docs[1]


# ------------------------------------------------------------------ fuzz
COLS = ["time [s]", "displacement [m]", "force [N]", "current [A]", "flow [m^3/s]", "dp [Pa]", "precharge [Pa]",
        "velocity [m/s]"]


@settings(max_examples=FUZZ, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cols=st.lists(st.sampled_from(COLS), min_size=1, max_size=6, unique=True), n=st.integers(0, 400),
       fs=st.sampled_from([1.0, 200.0, 1000.0, 1024.0, 5000.0]), scale=st.sampled_from([1e-6, 1e-3, 1.0, 1e3, -1.0]),
       labels=st.sampled_from([None, "piston_rebound", "random", "static", "P4.01bar_I0.32", "x"]),
       test=st.sampled_from([None, "flowbench", "topmount", "compliance", "friction"]))
def test_fuzz_fit_records_read_or_refused(tmp_path_factory, cols, n, fs, scale, labels, test):
    """What `fit` reads: any record is accepted only if plausible, else one DataError naming the file."""
    t = np.arange(n) / fs
    data = {c: (t if c == "time [s]" else scale * np.sin(2 * np.pi * 3 * t + j)) for j, c in enumerate(cols)}
    if labels is not None:
        data["run"] = labels
    p = write_frame(tmp_path_factory.mktemp("fit") / "piston_rebound.parquet", pd.DataFrame(data), {})
    try:
        df, _ = read_record(p, test, conf=CONF, require=("time", "force", "displacement|velocity"))
    except DataError as e:
        assert str(p) in str(e)
        return
    assert len(df) >= 2 and "time [s]" in df


@settings(max_examples=FUZZ, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(units=st.lists(st.sampled_from(["s", "ms", "mm", "m", "kN", "N", "bar", "g", "furlong", 3, None]),
                      min_size=4, max_size=4),
       quantities=st.lists(st.sampled_from(["time", "displacement", "force", "rod acceleration", "dp", "forse", "run"]),
                           min_size=4, max_size=4),
       protocol=st.sampled_from([None, "monosine", "compliance", 5, "nope"]), extra=st.sampled_from([{}, {"csv": [1]},
                                {"constants": {"current": {"value": "x", "unit": "A"}}}, {"run": 7}, {"columns": 3}]))
def test_fuzz_import_mappings_write_a_readable_record_or_refuse(tmp_path_factory, units, quantities, protocol, extra):
    tmp = tmp_path_factory.mktemp("imp")
    src = _import_src(tmp)
    cols = {c: {"quantity": q, "unit": u} for c, q, u in zip("txFa", quantities, units)}
    mapping = {"columns": cols, **({"protocol": protocol} if protocol is not None else {}), **extra}
    out = tmp / "own" / "c.parquet"
    try:
        import_measurement(src, mapping, out)
    except UserError as e:
        assert str(e) and not out.exists()
        return
    read_record(out, None, conf=CONF)  # what was written reads back through the same checks
