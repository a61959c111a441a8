"""Hostile inputs found by an outside review of the entry points (round 3):
a source overwritten by its own import, records read without a protocol
that were too short or had a velocity channel off by a unit or a sign,
--bounds files whose typos or bad values were ignored or failed with a
traceback after the fit, plot outputs unchecked, Ctrl-C as a traceback,
fit.json beside plots of another run. Each test fails when its check is
removed (SYNTHETIC records)."""

from __future__ import annotations

import math
import os

import numpy as np
import pandas as pd
import pytest

from dampertwin import cli
from dampertwin.cli import main
from dampertwin.io import write_frame
from dampertwin.io.outdir import OutputError, check_out_dir

from test_reliability_io import CONF, _scaled, refused


def device(fs=1000.0, T=8.0):
    """A friction-device record without protocol: 0.5 Hz, 10 mm, velocity column, Coulomb + viscous force."""
    t = np.arange(int(T * fs) + 1) / fs
    w = 2 * math.pi * 0.5
    x, v = 0.01 * np.sin(w * t), 0.01 * w * np.cos(w * t)
    return pd.DataFrame({"time [s]": t, "displacement [m]": x, "velocity [m/s]": v,
                         "force [N]": 40.0 * np.tanh(v / 1e-3) + 300.0 * v})


def _err(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err


# ------------------------------------------------------------------ records read without a protocol
def test_a_plausible_device_record_passes(tmp_path):
    p = write_frame(tmp_path / "d.parquet", device(), {"synthetic": True})
    from dampertwin.io import read_record
    read_record(p, None, conf=CONF)


@pytest.mark.parametrize("make, needles", [
    (lambda: device().iloc[:20], ("20 samples", "at least 100 samples over 0.1 s")),
    (lambda: device().assign(**{"velocity [m/s]": 0.0}), ("'velocity [m/s]' is constant",)),
    (lambda: _scaled(device(), "velocity [m/s]", 1e3), ("values in mm/s under a [m/s] header",)),
    (lambda: _scaled(device(), "velocity [m/s]", -1.0), ("velocity sign flipped",)),
    (lambda: device().assign(**{"velocity [m/s]": np.random.default_rng(1).normal(0, 0.03, len(device()))}),
     ("is not the displacement's rate",)),
], ids=["short", "dead velocity", "mm/s", "flipped velocity", "unrelated velocity"])
def test_device_record_refused_naming_the_column(tmp_path, make, needles):
    refused(tmp_path, make(), None, *needles)


# ------------------------------------------------------------------ --bounds files
@pytest.mark.parametrize("submodel, text, needle", [
    ("friction", "paramters:\n  - {name: F_c, bounds: [0, 50]}\n", "unknown key(s) paramters for a friction fit"),
    ("friction", "parameters:\n  - {name: F_c, bounds: [0, 50], sclae: log}\n", "parameters item 0"),
    ("friction", "parameters: {F_c: [0, 50]}\n", "expected a non-empty list"),
    ("friction", "parameters: []\n", "expected a non-empty list"),
    ("friction", "parameters:\n  - {name: F_c, bounds: [0, 5]}\n  - {name: F_c, bounds: [0, 6]}\n",
     "F_c listed more than once"),
    ("friction", "fixed: {F_c: abc}\n", "fixed: F_c = 'abc'; expected a finite number"),
    ("friction", "fixed: {F_c: .nan}\n", "expected a finite number"),
    ("friction", "fixed: {nosuch: 3}\n", "unknown friction parameter 'nosuch'"),
    ("friction", "fixed: {F_c: 3}\nparameters:\n  - {name: F_c, bounds: [0, 5]}\n", "both fixed and searched"),
    ("valve", "fixed: {F_c: 3}\n", "unknown key(s) fixed for a valve fit"),
    ("valve", "input_cutoff: -5\n", "input_cutoff: expected a positive frequency"),
    ("valve", "input_cutoff: abc\n", "input_cutoff: expected a positive frequency"),
    ("valve", "bench: {bench_volume: -1}\n", "bench: expected bench_volume"),
    ("valve", "ga: {populaton: 4}\n", "unknown key(s) populaton"),
    ("valve", "ga: {population: 0}\n", "population 0; expected an integer >= 2"),
    ("valve", "parameters:\n  - {name: a, bounds: [50, .inf]}\n", "two finite numbers"),
    ("valve", "parameters:\n  - {name: a, window: [2, 0.5]}\n", "f_lo < f_hi"),
])
def test_bounds_file_errors_are_one_line_before_any_fit(tmp_path, capsys, submodel, text, needle):
    """Each fails in well under the GA's first generation (no simulation runs) with one line naming the key."""
    b = tmp_path / "b.yaml"
    b.write_text(text)
    if submodel == "friction":
        data = write_frame(tmp_path / "d.parquet", device(), {"synthetic": True})
        argv = ["fit", "friction", "--data", str(data)]
    else:
        from test_reliability_io import flow
        data = write_frame(tmp_path / "piston_intake.parquet", flow("piston_intake"),
                           {"protocol": "flowbench", "synthetic": True})
        argv = ["fit", "valve", "--valve", "piston_intake", "--data", str(data)]
        if "ga:" not in text:  # the command line's budget would replace the file's
            argv += ["--population", "4", "--generations", "1"]
    out = tmp_path / "o"
    assert main([*argv, "--bounds", str(b), "--out", str(out)]) == 2
    assert needle in _err(capsys)
    assert not (out / "fit.json").exists()


def test_a_fixed_friction_parameter_leaves_the_default_search(tmp_path):
    """fixed: {F_c: 25} without parameters: the search from the record leaves F_c out and holds it at 25 N."""
    from dampertwin.cli_fit_files import fit_friction
    data = write_frame(tmp_path / "d.parquet", device(), {"synthetic": True})
    r = fit_friction(data, fixed={"F_c": 25.0}, starts=2)
    assert "F_c" not in r["parameters"] and r["fixed"]["F_c"] == 25.0


# ------------------------------------------------------------------ outputs
def test_import_onto_its_own_source_is_refused_and_the_source_kept(tmp_path, capsys):
    src = write_frame(tmp_path / "src.parquet", device(), {"synthetic": True})
    before = src.read_bytes()
    m = tmp_path / "m.yaml"
    m.write_text("synthetic: true\ncolumns:\n  time [s]: {quantity: time, unit: s}\n")
    assert main(["import", str(src), "--map", str(m), "--out", str(src)]) == 2
    assert "is the source file" in _err(capsys) and src.read_bytes() == before


def test_plot_output_and_measured_folder_checked_first(tmp_path, capsys):
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    assert main(["plot", "baseline_1.6", "--out", str(blocker)]) == 2
    assert "exists and is not a folder" in _err(capsys)
    assert main(["plot", "baseline_1.6", "--out", str(tmp_path / "p"), "--measured", str(tmp_path / "none")]) == 2
    assert "--measured" in _err(capsys) and not (tmp_path / "p").exists()


def test_existing_writable_output_needs_no_writable_parent(tmp_path, monkeypatch):
    """A writable OUT under a read-only folder: fit and import write inside it (accepted); discrepancy
    replaces OUT through a sibling, so it needs the parent (refused)."""
    out = tmp_path / "ro" / "w"
    out.mkdir(parents=True)
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(out.parent) else real(p, mode))
    check_out_dir(out)
    with pytest.raises(OutputError, match="not writable"):
        check_out_dir(out, sibling=True)
    with pytest.raises(OutputError, match="not writable"):
        check_out_dir(out.parent / "new")


def test_ctrl_c_is_one_line_and_exit_130(monkeypatch, capsys):
    def interrupted(argv):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_main", interrupted)
    assert main(["design", "show"]) == 130
    assert "interrupted" in _err(capsys)


def test_fit_json_is_written_after_the_plots(tmp_path, monkeypatch):
    """A run killed while plotting leaves no fit.json (an earlier run's is removed first), so the folder
    never shows a fit.json beside plots it does not describe."""
    import dampertwin.cli_fit_files as cff
    data = write_frame(tmp_path / "d.parquet", device(), {"synthetic": True})
    out = tmp_path / "o"
    cff.fit_friction(data, out=out, starts=2)
    assert (out / "fit.json").is_file()

    def killed(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(cff, "friction_plots", killed)
    with pytest.raises(KeyboardInterrupt):
        cff.fit_friction(data, out=out, starts=2)
    assert not (out / "fit.json").exists()


# ------------------------------------------------------------------ the design's P/Q map
@pytest.mark.parametrize("col, k, needle", [("dp [Pa]", 1e-5, "values in bar"), ("flow [m^3/s]", 60_000.0, "l/min"),
                                            ("current [A]", 1e3, "values in mA")])
def test_pq_map_in_another_unit_is_refused(tmp_path, col, k, needle):
    """The baseline's map with one column written in a common other unit: `design check` names the column."""
    import shutil

    from dampertwin.design import DesignError, load
    from test_reliability_io import ROOT
    shutil.copy(ROOT / "conf" / "design" / "baseline.yaml", tmp_path / "d.yaml")
    df = pd.read_csv(ROOT / "conf" / "design" / "active_valve_baseline.csv")
    df[col] = df[col] * k
    df.to_csv(tmp_path / "active_valve_baseline.csv", index=False)
    load(ROOT / "conf" / "design" / "baseline.yaml")  # the shipped map passes
    with pytest.raises(DesignError) as ei:
        load(tmp_path / "d.yaml")
    assert f"column {col!r}" in str(ei.value) and needle in str(ei.value)


# ------------------------------------------------------------------ a lab run stopped half-way
def test_a_stopped_lab_run_leaves_a_marker_the_workflow_refuses(tmp_path, monkeypatch):
    """The lab writes record by record; a run stopped after its first record leaves OUT/.incomplete, which the
    discrepancy workflow refuses to read; a finished run removes it (records faked: no simulation)."""
    import dampertwin.lab as lab
    from dampertwin.discrepancy.entry import DiscrepancyError, read_units
    from test_reliability_io import ROOT
    calls = {"n": 0}

    def fake(conf, sample_doc, nominal, test, case, seed, out):
        calls["n"] += 1
        if calls["n"] == 2 and stop:
            raise KeyboardInterrupt
        p = tmp_path / "o" / test / f"{case}.parquet"
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"")
        return str(p)

    monkeypatch.setattr(lab, "_measure_and_write", fake)
    only = [("compliance", "baseline"), ("friction", "baseline")]
    stop = True
    with pytest.raises(KeyboardInterrupt):
        lab.run_lab(ROOT / "conf" / "lab" / "sample.yaml", tmp_path / "o", only=only, workers=1, progress=False)
    assert (tmp_path / "o" / ".incomplete").is_file()
    with pytest.raises(DiscrepancyError, match="did not finish"):
        read_units(tmp_path / "o", None, CONF, {}, {})
    stop, calls["n"] = False, 0
    lab.run_lab(ROOT / "conf" / "lab" / "sample.yaml", tmp_path / "o", only=only, workers=1, progress=False)
    assert not (tmp_path / "o" / ".incomplete").exists()


# ------------------------------------------------------------------ import mappings and the current
@pytest.mark.parametrize("extra, needle", [
    ("settings: {rebound: 3}\n", "unknown key(s) settings"),
    ("time_offset: yes_please\n", "time_offset: 'yes_please'; expected true or false"),
    ("columns:\n  t: {quantity: time, unit: s}\n  x: {quantity: displacement, unit: m, scael: 2}\n",
     "column 'x': unknown key(s) scael"),
], ids=["top-level typo", "time_offset", "column typo"])
def test_import_mapping_typos_are_refused(tmp_path, capsys, extra, needle):
    src = tmp_path / "s.csv"
    device().rename(columns={"time [s]": "t", "displacement [m]": "x", "force [N]": "F"}).drop(
        columns="velocity [m/s]").to_csv(src, index=False)
    cols = "columns:\n  t: {quantity: time, unit: s}\n  x: {quantity: displacement, unit: m}\n"
    m = tmp_path / "m.yaml"
    m.write_text("synthetic: true\n" + (extra if extra.startswith("columns") else cols + extra))
    out = tmp_path / "o.parquet"
    assert main(["import", str(src), "--map", str(m), "--out", str(out)]) == 2
    assert needle in _err(capsys) and not out.exists()


@pytest.mark.parametrize("k, needle", [(-1.0, "is negative"), (0.9 / 1.6, "where the run label names 1.6 A")])
def test_a_current_against_its_run_label_is_refused(tmp_path, k, needle):
    from test_reliability_io import mono
    refused(tmp_path, _scaled(mono(), "current [A]", k), "monosine", needle)


def test_a_non_numeric_cell_is_named_with_its_row(tmp_path, capsys):
    src = tmp_path / "s.csv"
    df = device().drop(columns="velocity [m/s]").rename(columns={"time [s]": "t", "displacement [m]": "x",
                                                                 "force [N]": "F"})
    df["F"] = df["F"].astype(object)
    df.loc[6, "F"] = ""
    df.to_csv(src, index=False)
    m = tmp_path / "m.yaml"
    m.write_text("columns:\n  t: {quantity: time, unit: s}\n  x: {quantity: displacement, unit: m}\n"
                 "  F: {quantity: force, unit: N}\n")
    assert main(["import", str(src), "--map", str(m), "--out", str(tmp_path / "o.parquet")]) == 2
    assert "1 non-numeric values (the first, data row 7: an empty cell" in _err(capsys)


@pytest.mark.parametrize("value, needle", [(-9.0e8, "expected the same sign"), (9.0e5, "x the nominal part's")])
def test_a_truth_sample_value_of_another_sign_or_unit_is_refused(tmp_path, value, needle):
    """oil.K0 negative or 1000x too soft (Pa written as kPa): refused when the sample is checked, naming the key,
    not as a step-size underflow in the compliance test."""
    import yaml

    from dampertwin.design import load
    from dampertwin.lab import LabError, check_sample, load_sample
    from test_reliability_io import ROOT
    doc = yaml.safe_load((ROOT / "conf" / "lab" / "sample.yaml").read_text())
    doc["truth"]["values"]["oil.K0"] = value
    p = tmp_path / "s.yaml"
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(LabError, match="oil.K0") as ei:
        check_sample(load_sample(p), load(ROOT / "conf" / "lab" / "nominal.yaml"))
    assert needle in str(ei.value)


def test_a_lab_folder_of_another_sample_is_refused(tmp_path):
    import dampertwin.lab as lab
    from test_reliability_io import ROOT
    rec = write_frame(tmp_path / "o" / "compliance" / "baseline.parquet", device(),
                      {"synthetic": True, "sample_hash": "0123456789abcdef"})
    with pytest.raises(lab.LabError, match="holds records of another sample"):
        lab.run_lab(ROOT / "conf" / "lab" / "sample.yaml", tmp_path / "o", only=[("friction", "baseline")],
                    workers=1, progress=False)
    assert rec.is_file() and not (tmp_path / "o" / ".incomplete").exists()
