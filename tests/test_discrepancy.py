"""Discrepancy workflow (issue 11) on SYNTHETIC lab data with hidden effects:
a control says `none`, a clearly isolable hidden effect (piston leakage at a
large gap) is named, an artefact outside the library (load-cell crosstalk)
is `unexplained`, the augmented design loads and round-trips, bad input
exits 2 naming the file (the hidden oil heating and pressure-loaded seal
scenarios are `slow`). CI budget: the tests use compliance + two
mono-sine cases (no random record) and one lab generation per sample. The
methods' tests (features, gate, parameter choice, pairs):
tests/test_discrepancy_method.py."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml

from dampertwin.cli import main as cli
from dampertwin.design import load, loads
from dampertwin.discrepancy import entry
from dampertwin.discrepancy.hidden import hidden_sample, loadcell_crosstalk
from dampertwin.io import read_meta, write_frame
from dampertwin.lab import load_sample, run_lab

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "conf" / "design" / "baseline.yaml"
ONLY = [("compliance", "baseline"), ("monosine", "baseline_1.6"), ("monosine", "baseline_0.32")]
TESTS = {"compliance": ["baseline"], "monosine": ["baseline_1.6", "baseline_0.32"]}
KEYS = {"verdict", "effects", "group", "candidates", "gap", "where", "design"}


def _lab(tmp: Path, name: str, seed: int, only=ONLY, **spec) -> Path:
    base = {k: v for k, v in load_sample(ROOT / "conf" / "lab" / "lab2" / "sample.yaml").items() if not k.startswith("_")}
    s = hidden_sample(base, **spec)
    s["nominal"] = str(ROOT / "conf" / "lab" / "nominal.yaml")
    p = tmp / f"{name}.yaml"
    p.write_text(yaml.safe_dump(s))
    out = tmp / name
    run_lab(p, out, seed=seed, only=only, progress=False, workers=1)
    return out


# ``control`` (the nominal part on the shipped lab's benches) and ``control_serial_run``: tests/conftest.py


@pytest.fixture(scope="module")
def leak(tmp_path_factory) -> Path:
    """Piston leakage at a large (worn-band) gap, otherwise nominal."""
    return _lab(tmp_path_factory.mktemp("lab"), "leak", 12, effects={"piston_leakage": True},
                values={_leak_key(): 6e-5})


@pytest.fixture(scope="module")
def control_run(control, tmp_path_factory) -> tuple[Path, dict]:
    """The workflow on ``control`` (seed 0, records in a 2-process pool, the default on 2 cores):
    (OUT, verdict). Run once and only read by the tests that need it (the run takes minutes on CI)."""
    out = tmp_path_factory.mktemp("control_run") / "out"
    return out, _run(control, out, workers=2)


@pytest.fixture(scope="module")
def compliance_only_run(control, tmp_path_factory) -> tuple[Path, Path, dict]:
    """The workflow on ``control``'s compliance record alone (seed 0, in this process), written into
    an earlier output as a DVC stage leaves it (its outs removed, its .gitignore and a stale
    resolvability.json kept): (parent, OUT, verdict). Shared by the test of records that cannot see
    an effect and the test that an earlier output is replaced (neither property needs more records)."""
    tmp = tmp_path_factory.mktemp("compliance_only")
    only = tmp / "m"
    shutil.copytree(control / "compliance", only / "compliance")
    prev = tmp / "prev"
    prev.mkdir()
    (prev / ".gitignore").write_text("/plots\n")
    (prev / "resolvability.json").write_text("[]")
    doc = entry.main(str(DESIGN), str(only), str(prev), profile="ci", seed=0, progress=False,
                     tests={"compliance": ["baseline"]}, workers=1)
    assert json.loads((prev / "verdict.json").read_text()) == doc
    return tmp, prev, doc


def _leak_key() -> str:
    """The leakage gap's key: ``piston_leakage.gap`` with the effect-parameter API, else the constant."""
    d = load(ROOT / "conf" / "lab" / "nominal.yaml")
    if hasattr(d, "effect_parameters") and any(e.key == "piston_leakage.gap" for e in d.effect_parameters()):
        return "piston_leakage.gap"
    return "constants.leak_gap"


def _run(measured: Path, out: Path, seed: int = 0, workers: int | None = None) -> dict:
    doc = entry.main(str(DESIGN), str(measured), str(out), profile="ci", seed=seed, progress=False, tests=TESTS,
                     workers=workers)
    assert json.loads((out / "verdict.json").read_text()) == doc
    assert set(doc) == KEYS
    assert (out / "report.md").is_file() and list((out / "plots").glob("*.png"))
    return doc


def test_control_says_none_and_design_round_trips(control_run):
    out, doc = control_run
    assert doc["verdict"] == "none", doc
    assert doc["effects"] == [] and doc["design"] == "design.yaml"
    d = load(out / "design.yaml", map_dirs=[ROOT / "conf" / "design"])
    again = loads(d.dumps(), base_dir=str(ROOT / "conf" / "design"))
    assert again.hash() == d.hash()
    assert not d.effects["piston_leakage"]
    # what these records (compliance + two mono-sine currents, seconds long) could have seen: the
    # active valve's lag and the top mount's play move the mono-sine acceleration far beyond the
    # record gate; oil heating over seconds (ratio ~0) cannot show, whatever the gate
    rs = {r["effect"]: r for r in json.loads((out / "resolvability.json").read_text())}
    assert {"piston_leakage", "oil_thermal", "active_valve_lag", "top_mount_backlash"} <= set(rs)
    assert rs["active_valve_lag"]["resolvable"] and rs["top_mount_backlash"]["resolvable"], rs
    assert rs["oil_thermal"]["resolvable"] is False and rs["oil_thermal"]["ratio"] < 0.01, rs
    assert rs["oil_thermal"]["separating_test"] == "thermal"
    assert "What these records can resolve" in (out / "report.md").read_text()


def test_records_that_cannot_see_an_effect_at_all(compliance_only_run):
    """Only the compliance record (rod fixed: the top mount's play cannot act): `none`, and the
    resolvability check says the backlash has no signature at all there (a zero ratio once crashed
    the decision log)."""
    _, out, doc = compliance_only_run
    assert doc["verdict"] == "none", doc
    rs = {r["effect"]: r for r in json.loads((out / "resolvability.json").read_text())}
    assert rs["top_mount_backlash"]["ratio"] == 0 and rs["top_mount_backlash"]["min_factor"] is None, rs
    assert rs["top_mount_backlash"]["resolvable"] is False
    assert "top_mount_backlash 0.00 (no signature at all on these records" in (out / "report.md").read_text()


def test_record_workers_give_the_same_numbers(control_run, control_serial_run):
    """The records simulated in a 2-process pool (the default on 2 cores) and in this process: same bytes."""
    (pool, a), (serial, b) = control_run, control_serial_run
    assert a == b
    for name in ("verdict.json", "resolvability.json", "design.yaml"):
        assert (pool / name).read_bytes() == (serial / name).read_bytes(), name


def test_hidden_leakage_is_named(leak, tmp_path):
    doc = _run(leak, tmp_path / "out", seed=3)
    assert doc["verdict"] == "named", doc
    assert doc["effects"][0] == "piston_leakage"
    assert doc["gap"]["closed_fraction"] >= 0.5
    assert doc["where"] and all(set(w) == {"test", "case", "phase_or_band", "excess"} for w in doc["where"])
    # the report states the named fit's reach beside its name: the fractions the closure gate passed
    report = (tmp_path / "out" / "report.md").read_text()
    m = re.search(r"The named fit \(`piston_leakage[^`]*`.*? closes (\d+) % of the whole held-out gap and "
                  r"(\d+) % of the excess in the (\d+) held-out record", report)
    assert m and max(int(m.group(1)), int(m.group(2))) >= 50 and int(m.group(3)) >= 1, report[:1500]
    cand = next(c for c in doc["candidates"] if c["effect"] == "piston_leakage")
    gap = next(v for k, v in cand["parameters"].items() if "gap" in k)
    assert 2.5e-5 < gap < 1.2e-4  # the hidden 60 um, within what the records can tell
    d = load(tmp_path / "out" / "design.yaml", map_dirs=[ROOT / "conf" / "design"])
    assert d.effects["piston_leakage"]
    assert d.hash() == loads(d.dumps(), base_dir=str(ROOT / "conf" / "design")).hash()


@pytest.mark.slow  # two warm-up labs and two workflow runs: 128 s on the 2-core machine at load 4
def test_oil_heating_is_named_on_warm_up_records(tmp_path):
    """oil_thermal moves the force of seconds-long records by < 1 N, so only the warm-up test's
    thermocouple shows it. Hidden at its typical magnitude, the temperature rise names the effect
    and the augmented design follows the measured rise; the nominal part on the same bench: `none`."""
    thermal, tests = [("thermal", "baseline")], {"thermal": ["baseline"]}
    hot = _lab(tmp_path, "hot", 21, only=thermal, effects={"oil_thermal": True})
    cold = _lab(tmp_path, "cold", 22, only=thermal)
    doc = entry.main(str(DESIGN), str(hot), str(tmp_path / "o_hot"), profile="ci", seed=0, progress=False,
                     tests=tests, workers=1)
    assert doc["verdict"] == "named" and doc["effects"] == ["oil_thermal"], doc
    cand = next(c for c in doc["candidates"] if c["effect"] == "oil_thermal")
    assert cand["heldout_gap_before"] > 5.0 and cand["heldout_gap_after"] < 1.0, cand  # 1 = noise
    assert doc["gap"]["closed_fraction"] >= 0.8
    assert any("temperature rise" in w["phase_or_band"] for w in doc["where"]), doc["where"]
    d = load(tmp_path / "o_hot" / "design.yaml", map_dirs=[ROOT / "conf" / "design"])
    assert d.effects["oil_thermal"]
    doc = entry.main(str(DESIGN), str(cold), str(tmp_path / "o_cold"), profile="ci", seed=0, progress=False,
                     tests=tests, workers=1)
    assert doc["verdict"] == "none", doc


@pytest.mark.slow  # two friction labs and two workflow runs: 54 s at load 4
def test_pressure_loaded_seal_is_named_on_friction_records(tmp_path):
    """On the standard tests a seal that rubs harder with the chamber pressure is a ~2 % force gain plus a
    Coulomb step (the calibration absorbs it). The friction test strokes the damper slowly at two gas
    precharges: hidden at its typical magnitude, the seal is named from those records, and the fit finds
    its magnitude; the nominal part on the same bench: `none`."""
    fr, tests = [("friction", "baseline")], {"friction": ["baseline"]}
    seal = _lab(tmp_path, "seal", 31, only=fr, effects={"seal_friction_pressure": True},
                values={"seal_friction_pressure.k_p": 1.0e-5})
    plain = _lab(tmp_path, "plain", 32, only=fr)
    doc = entry.main(str(DESIGN), str(seal), str(tmp_path / "o_seal"), profile="ci", seed=0, progress=False,
                     tests=tests, workers=1)
    assert doc["verdict"] == "named" and doc["effects"] == ["seal_friction_pressure"], doc
    cand = next(c for c in doc["candidates"] if c["effect"] == "seal_friction_pressure")
    assert 0.5e-5 < cand["parameters"]["seal_friction_pressure.k_p"] < 2.0e-5, cand
    assert cand["heldout_gap_after"] < cand["heldout_gap_before"], cand
    assert load(tmp_path / "o_seal" / "design.yaml", map_dirs=[ROOT / "conf" / "design"]).effects["seal_friction_pressure"]
    doc = entry.main(str(DESIGN), str(plain), str(tmp_path / "o_plain"), profile="ci", seed=0, progress=False,
                     tests=tests, workers=1)
    assert doc["verdict"] == "none", doc


def test_a_varying_precharge_column_is_refused():
    """The friction test's precharge column is the run's gas fill (one value): a varying trace (a chamber
    pressure logged under that name) is refused naming the column, never read as its first sample."""
    import pandas as pd
    from dampertwin.discrepancy import features as F

    t = np.arange(2000) / 1000.0
    df = pd.DataFrame({"time [s]": t, "displacement [m]": 0.005 * np.sin(2 * np.pi * 1.6 * t),
                       "force [N]": 80 * np.cos(2 * np.pi * 1.6 * t), "precharge [Pa]": 1.4e6})
    u = F.make_unit("friction", "baseline", "P14bar_I0.32", "damper", 0.32, df, {"force": 1000.0})
    assert u.overrides == {"oil.P_0": 1.4e6}
    df["precharge [Pa]"] = 1.4e6 + 2e5 * np.sin(2 * np.pi * 1.6 * t)
    with pytest.raises(ValueError, match="'precharge \\[Pa\\]' varies"):
        F.make_unit("friction", "baseline", "P14bar_I0.32", "damper", 0.32, df, {"force": 1000.0})


def test_out_of_library_artefact_is_unexplained(control, tmp_path):
    """Load-cell crosstalk from the stroke channel: no library effect has this signature."""
    art = tmp_path / "artefact"
    shutil.copytree(control, art)
    for f in art.glob("*/*.parquet"):
        df = pq.read_table(f).to_pandas()
        write_frame(f, loadcell_crosstalk(df, 0.03), {**read_meta(f), "artefact": "load-cell crosstalk 3 %"})
    doc = _run(art, tmp_path / "out")
    assert doc["verdict"] == "unexplained", doc
    assert doc["effects"] == []
    # what the library could have shown through the misfit the calibrated design leaves: the model
    # error only raises a record's gate, and does so where it exceeds the noise quantile
    rs = json.loads((tmp_path / "out" / "resolvability.json").read_text())
    assert rs and all(r["ratio"] <= r["ratio_noise"] + 1e-9 for r in rs if r["ratio"] is not None), rs
    assert any(r["ratio"] < 0.9 * r["ratio_noise"] for r in rs if r["ratio"] is not None), rs
    assert "times the record's Birge ratio" in (tmp_path / "out" / "report.md").read_text()


def _exit(argv, capsys):
    code = cli(argv)
    return code, capsys.readouterr().err


def test_bad_input_exits_2_naming_the_file(tmp_path, capsys, control):
    out = str(tmp_path / "out")
    empty = tmp_path / "empty"
    empty.mkdir()
    code, err = _exit(["discrepancy", "--design", str(DESIGN), "--measured", str(empty), "--out", out], capsys)
    assert code == 2 and str(empty) in err and "no test records" in err
    bad_design = tmp_path / "bad.yaml"
    text = DESIGN.read_text() + "\nnot_a_key: 1\n"
    bad_design.write_text(text)
    (tmp_path / "active_valve_baseline.csv").write_text((DESIGN.parent / "active_valve_baseline.csv").read_text())
    code, err = _exit(["discrepancy", "--design", str(bad_design), "--measured", str(control), "--out", out], capsys)
    assert code == 2 and str(bad_design) in err
    broken = tmp_path / "broken"
    (broken / "monosine").mkdir(parents=True)
    (broken / "monosine" / "baseline_1.6.parquet").write_bytes(b"not a parquet file")
    code, err = _exit(["discrepancy", "--design", str(DESIGN), "--measured", str(broken), "--out", out], capsys)
    assert code == 2 and "baseline_1.6.parquet" in err
    missing = tmp_path / "nope.yaml"
    code, err = _exit(["discrepancy", "--design", str(missing), "--measured", str(control), "--out", out], capsys)
    assert code == 2 and str(missing) in err
    assert not (tmp_path / "out").exists()
    assert np.isfinite(2.0)


def test_out_folder_and_seed_are_checked_before_any_work(tmp_path, capsys, control, monkeypatch):
    """OUT is replaced as a whole: a folder that is not an earlier output, or that holds the working
    directory, the measured data or the design, is refused (exit 2) and left as it was; so are a
    file as OUT, a file as its parent, and a negative seed."""
    base = ["discrepancy", "--design", str(DESIGN), "--measured", str(control), "--out"]
    keep = tmp_path / "mine"
    keep.mkdir()
    (keep / "notes.txt").write_text("mine")
    code, err = _exit(base + [str(keep)], capsys)
    assert code == 2 and "does not write" in err and (keep / "notes.txt").read_text() == "mine"
    monkeypatch.chdir(keep)
    code, err = _exit(base + ["."], capsys)
    assert code == 2 and "working directory" in err and (keep / "notes.txt").is_file()
    code, err = _exit(base + [str(control.parent)], capsys)
    assert code == 2 and "measured folder" in err and control.is_dir()
    f = tmp_path / "file"
    f.write_text("x")
    assert _exit(base + [str(f)], capsys)[0] == 2 and f.read_text() == "x"
    code, err = _exit(base + [str(f / "sub")], capsys)
    assert code == 2 and "is a file" in err
    code, err = _exit(base + [str(tmp_path / "o"), "--seed", "-1"], capsys)
    assert code == 2 and "--seed -1" in err and not (tmp_path / "o").exists()


def test_an_earlier_output_is_replaced(compliance_only_run):
    """An earlier output, as a DVC stage leaves it (its outs removed, its .gitignore and an untracked
    file kept), is accepted as OUT and replaced: the run (the compliance record alone; which records
    does not matter to how OUT is written) keeps the .gitignore, rewrites the stale file and leaves no
    temporary folder."""
    parent, prev, doc = compliance_only_run
    assert doc["verdict"] == "none" and (prev / ".gitignore").read_text() == "/plots\n"
    assert json.loads((prev / "resolvability.json").read_text())
    assert (prev / "report.md").is_file() and (prev / "design.yaml").is_file()
    assert [p.name for p in parent.iterdir() if p.name.startswith(".prev")] == []  # no temp folder left


def test_a_single_record_names_no_effect(tmp_path):
    """With one record there is nothing to hold out: an in-sample fit always improves with extra
    parameters, so no effect is named -- not even the active valve's lag, which the 0.32 A mono-sine
    record shows far beyond noise (chi^2 ~18x its gate; without this rule it was `named` on its
    in-sample gain) -- and the report says the gaps are in-sample. (The lag of the valve's opening,
    issue 34, barely shows at 1.6 A, where the valve stays near its bleed: 0.02x the gate on the 1.6 A
    record, verdict `none`; the lag of the flow it replaced showed there.)"""
    base = {k: v for k, v in load_sample(ROOT / "conf" / "lab" / "lab2" / "sample.yaml").items() if not k.startswith("_")}
    s = hidden_sample(base, effects={"active_valve_lag": True})
    s["nominal"] = str(ROOT / "conf" / "lab" / "nominal.yaml")
    (tmp_path / "lag.yaml").write_text(yaml.safe_dump(s))
    run_lab(tmp_path / "lag.yaml", tmp_path / "m", seed=5, only=[("monosine", "baseline_0.32")], progress=False,
            workers=1)
    doc = entry.main(str(DESIGN), str(tmp_path / "m"), str(tmp_path / "out"), profile="ci", seed=0, progress=False,
                     tests={"monosine": ["baseline_0.32"]}, workers=1)
    assert doc["verdict"] == "unexplained", doc
    assert doc["effects"] == []
    report = (tmp_path / "out" / "report.md").read_text()
    assert "No held-out record" in report and "not named on in-sample fits" in report


def test_time_stamp_jitter_and_a_dead_accelerometer(control, tmp_path):
    """Time stamps within 1e-3 of an interval of the uniform grid are a uniform record (the reader and
    the excitation agree); beyond, the reader names the file. A flat accelerometer is a dead sensor."""
    from dampertwin.io import DataError, read_frame

    src = control / "monosine" / "baseline_1.6.parquet"
    df = pq.read_table(src).to_pandas()
    t = df["time [s]"].to_numpy(float)
    dt = t[1] - t[0]
    for shift, ok in ((5e-4, True), (5e-3, False)):
        bad = df.copy()
        bad.loc[100, "time [s]"] = t[100] + shift * dt
        path = tmp_path / f"jitter_{shift}" / "monosine" / "baseline_1.6.parquet"
        write_frame(path, bad, read_meta(src))
        if ok:
            read_frame(path, "monosine")
            doc_units = entry.read_units(path.parent.parent, load(DESIGN), ROOT / "conf",
                                         entry.load_config(ROOT / "conf")["features"],
                                         entry.load_config(ROOT / "conf")["profiles"]["ci"],
                                         {"monosine": ["baseline_1.6"]})
            assert doc_units[0]
        else:
            with pytest.raises(DataError, match="non-uniform sampling"):
                read_frame(path, "monosine")
    dead = df.copy()
    dead["rod acceleration [m/s^2]"] = 0.0
    path = tmp_path / "dead" / "monosine" / "baseline_1.6.parquet"
    write_frame(path, dead, read_meta(src))
    with pytest.raises(DataError, match="rod acceleration .* is constant"):
        read_frame(path, "monosine")
