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
import re

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
    ("friction", "fixed: {F_c: -5}\n", "fixed: F_c = -5 outside the physical range of the Coulomb friction force"),
    ("friction", "fixed: {k_b: 0}\n", "fixed: k_b = 0 outside the physical range of the bristle stiffness"),
    ("friction", "fixed: {F_s: 0}\nparameters:\n  - {name: F_c, bounds: [0, 200]}\n",
     "fixed: F_s = 0 outside the physical range of the static friction force"),
    ("friction", "fixed: {F_c: 3}\nparameters:\n  - {name: F_c, bounds: [0, 5]}\n", "both fixed and searched"),
    ("valve", "fixed: {F_c: 3}\n", "unknown key(s) fixed for a valve fit"),
    ("valve", "input_cutoff: -5\n", "input_cutoff: expected a positive frequency"),
    ("valve", "input_cutoff: abc\n", "input_cutoff: expected a positive frequency"),
    ("valve", "bench: {bench_volume: -1}\n", "bench: expected bench_volume"),
    ("valve", "ga: {populaton: 4}\n", "unknown key(s) populaton"),
    ("valve", "ga: {population: 0}\n", "population 0; expected an integer >= 2"),
    ("valve", "ga: {mutation_probability: abc}\n", "ga.mutation_probability 'abc'; expected the probability a "
                                                   "gene mutates [%] in (0, 100]"),
    ("valve", "ga: {mutation_probability: 500}\n", "ga.mutation_probability 500; expected"),
    ("valve", "ga: {reproduction_ratio: abc}\n", "ga.reproduction_ratio 'abc'; expected the share of the "
                                                 "population mating [%] in (0, 100]"),
    ("valve", "ga: {reproduction_ratio: -50, population: 4, generations: 1}\n", "ga.reproduction_ratio -50;"),
    ("valve", "ga: {elitism: -1}\n", "ga.elitism -1; expected an integer 0 <= elitism < population (20)"),
    ("valve", "ga: {elitism: 100}\n", "ga.elitism 100; expected an integer 0 <= elitism < population (20)"),
    ("valve", "parameters:\n  - {name: a, bounds: [50, .inf]}\n", "two finite numbers"),
    ("valve", "parameters:\n  - {name: a, window: [2, 0.5]}\n", "f_lo < f_hi"),
    ("valve", "parameters:\n  - {key: piston_intake.a, bounds: [50, 500]}\n  - {name: a, bounds: [60, 600]}\n",
     "piston_intake.a searched more than once"),
    ("valve", "objective: bogus\n", "objective: expected a mapping, got 'bogus'"),
    ("valve", "ga: [1, 2]\n", "ga: expected a mapping"),
    ("valve", "polish: 7\n", "polish: expected a mapping, got 7"),
    ("valve", "polish: {starts: 3}\n", "expected starts and max_nfev"),
    ("valve", "polish: {starts: -4, max_nfev: 10}\n", "polish: starts = -4; expected a positive integer"),
    ("topmount", "runs: sweep_A0.001_f10\n", "runs: 'sweep_A0.001_f10'; expected a list of run labels"),
    ("topmount", "static: yes\n", "static: expected a mapping"),
    ("topmount", "static: {run: static, order: 500}\n", "static.order: 500; expected an integer 1..5"),
    ("topmount", "determined: [1, 2]\n", "determined: expected a mapping"),
    ("topmount", "determined: {frequencies: [-5, 0], amplitude: -1}\n", "expected {frequencies: [Hz > 0, ...]"),
])
def test_bounds_file_errors_are_one_line_before_any_fit(tmp_path, capsys, submodel, text, needle):
    """Each fails in well under the GA's first generation (no simulation runs) with one line naming the key."""
    b = tmp_path / "b.yaml"
    b.write_text(text)
    if submodel in ("friction", "topmount"):  # the file is refused before the record is read
        data = write_frame(tmp_path / "d.parquet", device(), {"synthetic": True})
        argv = ["fit", submodel, "--data", str(data)]
    else:
        from test_reliability_io import flow
        data = write_frame(tmp_path / "piston_intake.parquet", flow("piston_intake"),
                           {"protocol": "flowbench", "synthetic": True})
        argv = ["fit", "valve", "--valve", "piston_intake", "--data", str(data)]
        if "ga:" not in text:  # the command line's budget would replace the file's
            argv += ["--population", "4", "--generations", "1"]
    out = tmp_path / "o"
    assert main([*argv, "--bounds", str(b), "--out", str(out)]) == 2
    err = _err(capsys)
    assert needle in err
    if needle.startswith("ga."):  # a GA setting's error names the --bounds file it came from
        assert f"{b}: ga." in err, err
    assert not (out / "fit.json").exists()


@pytest.mark.parametrize("bad", [{"mutation_probability": True}, {"mutation_probability": 0},
                                 {"reproduction_ratio": 101}, {"reproduction_ratio": float("nan")},
                                 {"elitism": 4}, {"elitism": 1.0}])
def test_ga_settings_name_their_source_and_key(bad):
    """Each GA setting checked for type and range, the error naming the source given (the file) and ga.<key>."""
    from dampertwin.calibration.ga import GASettings
    from dampertwin.errors import UserError

    c = {"population": 4, "reproduction_ratio": 80, "generations": 1, "mutation_probability": 10,
         "max_wall_s": 10, **bad}
    with pytest.raises(UserError, match=rf"^b\.yaml: ga\.{next(iter(bad))} .*; expected .*(\(0, 100\]|< population)"):
        GASettings.from_config(c, where="b.yaml")
    assert GASettings.from_config({**c, **{k: 3 for k in bad}}, where="b.yaml")  # a value in range passes


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
        p = tmp_path / "o" / test / f"{case}.parquet"  # a record of this sample, as the lab writes it
        return str(write_frame(p, device(), {"synthetic": True, "sample_hash": sample_doc["_hash"]}))

    monkeypatch.setattr(lab, "_measure_and_write", fake)
    only = [("compliance", "baseline"), ("friction", "baseline")]
    stop = True
    with pytest.raises(KeyboardInterrupt):
        lab.run_lab(ROOT / "conf" / "lab" / "sample.yaml", tmp_path / "o", only=only, workers=1, progress=False)
    assert (tmp_path / "o" / ".incomplete").is_file()
    with pytest.raises(DiscrepancyError, match="did not finish"):
        read_units(tmp_path / "o", None, CONF, {}, {})
    # a rerun of other tests leaves the marker while the stopped run's unwritten record is still missing
    stop, calls["n"] = False, 0
    lab.run_lab(ROOT / "conf" / "lab" / "sample.yaml", tmp_path / "o", only=[("topmount", "baseline")], workers=1,
                progress=False)
    assert (tmp_path / "o" / ".incomplete").read_text().splitlines()[2:] == ["friction/baseline"]
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


def test_a_text_cell_in_a_decimal_comma_export_is_named_not_the_first_number(tmp_path, capsys):
    """The shipped rig export (';' and decimal commas, csv: {decimal: ','}) with one text cell: pandas then
    leaves the whole column as text; the error names that cell and its row, not the column's first number."""
    from pathlib import Path

    ex = Path(__file__).resolve().parents[1] / "examples"
    lines = (ex / "rig_monosine.csv").read_text().splitlines()
    cells = lines[501].split(";")
    cells[2] = "abc"  # Kraft, data row 501
    lines[501] = ";".join(cells)
    src = tmp_path / "rig.csv"
    src.write_text("\n".join(lines) + "\n")
    assert main(["import", str(src), "--map", str(ex / "mapping.yaml"), "--out", str(tmp_path / "o.parquet")]) == 2
    err = _err(capsys)
    assert "column 'Kraft': 1 non-numeric values (the first, data row 501: 'abc'" in err, err


@pytest.mark.parametrize("cell, hint", [("12,5", "a decimal comma needs csv: {decimal: ','}"),
                                        ("-1.234,5e-3", "a decimal comma"),
                                        ("end of record", "a text line in the data"),
                                        ("F", "a text line in the data"),
                                        ("1 234,5", "a thousands separator"), ("1,234.5", "a thousands separator"),
                                        ("1\u00a0234", "a thousands separator")])
def test_a_non_numeric_cell_gets_the_hint_of_its_kind(tmp_path, capsys, cell, hint):
    """A footer or a repeated header row is not blamed on a decimal comma; a comma number is."""
    src = tmp_path / "s.csv"
    df = device().drop(columns="velocity [m/s]").rename(columns={"time [s]": "t", "displacement [m]": "x",
                                                                 "force [N]": "F"})
    df["F"] = df["F"].astype(object)
    df.loc[len(df) - 1, "F"] = cell
    df.to_csv(src, index=False)
    m = tmp_path / "m.yaml"
    m.write_text("columns:\n  t: {quantity: time, unit: s}\n  x: {quantity: displacement, unit: m}\n"
                 "  F: {quantity: force, unit: N}\n")
    assert main(["import", str(src), "--map", str(m), "--out", str(tmp_path / "o.parquet")]) == 2
    err = _err(capsys)
    assert hint in err and repr(cell) in err
    assert ("decimal comma" in err) == ("," in cell and "thousands" not in hint)


@pytest.mark.parametrize("header, kw, refused", [
    ("Logger v2\nt,x,F,F,G", {"header": 1}, "'F'"),             # a preamble the header re-read cannot parse
    ("t,x,F,F,G", {"dtype": {"t": float}}, "'F'"),              # keywords the re-read cannot take
    ("t,x,F,Status,Status", {"usecols": [0, 1, 2]}, None),     # the repeat is not read
    ("t,x,F,Status,Status", {"usecols": ["t", "x", "F"]}, None),
    ("t, x,x,F,G", {}, None),                                   # ' x' and 'x' are two names to pandas
    ("t,x,x.1,F,G", {}, None),                                  # the file really names a column 'x.1'
    ("t,x,x.1,x,G", {}, "'x'"),
])
def test_repeated_header_names_under_csv_keywords(tmp_path, header, kw, refused):
    from dampertwin.io import DataError, read_table
    p = tmp_path / "h.csv"
    p.write_text(header + "\n0,1,2,3,4\n1,2,3,4,5\n")
    if refused is None:
        assert len(read_table(p, kw)[0]) == 2
    else:
        with pytest.raises(DataError, match=f"names column {refused} more than once"):
            read_table(p, kw)


def test_a_header_naming_a_column_twice_is_refused(tmp_path, capsys):
    """pandas renames a repeated header name 'F.1' and the mapping would take the first column silently."""
    src = tmp_path / "s.csv"
    df = device().drop(columns="velocity [m/s]")
    lines = df.to_csv(index=False, sep=";").splitlines()
    lines[0] = "t;x;F;F"
    src.write_text("meta line\n" + "\n".join(f"{ln};0" if i else ln for i, ln in enumerate(lines)) + "\n")
    m = tmp_path / "m.yaml"
    m.write_text("csv: {sep: ';', skiprows: 1}\ncolumns:\n  t: {quantity: time, unit: s}\n"
                 "  x: {quantity: displacement, unit: m}\n  F: {quantity: force, unit: N}\n")
    out = tmp_path / "o.parquet"
    assert main(["import", str(src), "--map", str(m), "--out", str(out)]) == 2
    assert "names column 'F' more than once (pandas called a repeat 'F.1')" in _err(capsys) and not out.exists()
    src.write_text("meta line\n" + "\n".join(f"{ln};0" if i else ln.replace("F;F", "F;G")
                                              for i, ln in enumerate(lines)) + "\n")
    assert main(["import", str(src), "--map", str(m), "--out", str(out)]) == 0 and out.is_file()
    rec = tmp_path / "r.csv"
    df.to_csv(rec, index=False)
    rec.write_text(rec.read_text().replace("force [N]", "displacement [m]", 1))
    assert main(["kpi", "dyno", str(rec)]) == 2
    assert "names column 'displacement [m]' more than once" in _err(capsys)


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


# ------------------------------------------------------------------ a second outside review (inputs kept, not replaced)
def test_a_lab_folder_holding_an_imported_measurement_is_refused_and_kept(tmp_path):
    """The lab never writes synthetic data over a record it did not write (an imported one, no sample hash)."""
    import dampertwin.lab as lab
    from test_reliability_io import ROOT, fric
    rec = write_frame(tmp_path / "o" / "friction" / "baseline.parquet", fric(),
                      {"imported": True, "source": "my_rig.csv", "protocol": "friction", "synthetic": False})
    before = rec.read_bytes()
    with pytest.raises(lab.LabError, match="an imported measurement the lab did not write"):
        lab.run_lab(ROOT / "conf" / "lab" / "sample.yaml", tmp_path / "o", only=[("friction", "baseline")],
                    workers=1, progress=False)
    assert rec.read_bytes() == before and not (tmp_path / "o" / ".incomplete").exists()
    rec.write_bytes(b"garbage")  # nor over a file it cannot read; named in one line
    with pytest.raises(lab.LabError) as ei:
        lab.run_lab(ROOT / "conf" / "lab" / "sample.yaml", tmp_path / "o", only=[("friction", "baseline")],
                    workers=1, progress=False)
    assert f"holds {rec}, which is not a readable record (cannot read:" in str(ei.value)
    assert "\n" not in str(ei.value) and rec.read_bytes() == b"garbage"


@pytest.mark.parametrize("opt", ["--data", "--design"])
def test_a_fit_whose_output_folder_holds_an_input_is_refused_and_the_input_kept(tmp_path, capsys, opt):
    import shutil

    from test_reliability_io import ROOT, flow
    out = tmp_path / "o"
    out.mkdir()
    data = write_frame((out if opt == "--data" else tmp_path) / "piston_intake.parquet", flow("piston_intake"),
                       {"protocol": "flowbench", "synthetic": True})
    design = shutil.copy(ROOT / "conf" / "design" / "baseline.yaml", (out if opt == "--design" else tmp_path) / "d.yaml")
    kept = {p: p.read_bytes() for p in (data, design)}
    assert main(["fit", "valve", "--valve", "piston_intake", "--data", str(data), "--design", str(design),
                 "--population", "4", "--generations", "1", "--out", str(out)]) == 2
    assert f"holds the {opt} file" in _err(capsys)
    assert all(p.read_bytes() == b for p, b in kept.items()) and not (out / "fit.json").exists()
    # an input deeper below OUT is never written over (the fit writes directly in OUT): accepted
    from argparse import Namespace

    from dampertwin.cli_checks import check_args
    deep = write_frame(tmp_path / "sub" / "piston_intake.parquet", flow("piston_intake"),
                       {"protocol": "flowbench", "synthetic": True})
    check_args(Namespace(cmd="fit", submodel="valve", valve="piston_intake", data=str(deep), predict=[],
                         design=str(ROOT / "conf" / "design" / "baseline.yaml"), bounds=None, out=str(tmp_path)))


def test_a_searched_parameter_given_by_key_and_by_name_is_one_line_or_replaced():
    """`a` and `piston_intake.a` are one parameter: twice in one list is refused before any fit, and a
    --param by key replaces the --bounds file's item by name (the documented override)."""
    from dampertwin.calibration.approach1 import specs_from_config
    from dampertwin.cli_fit import _merge_items
    from dampertwin.design import load
    from test_reliability_io import ROOT
    d = load(ROOT / "conf" / "design" / "baseline.yaml")
    items = [{"key": "piston_intake.a", "bounds": [50.0, 500.0]}, {"name": "a", "bounds": [60.0, 600.0]}]
    with pytest.raises(Exception, match=r"b.yaml: piston_intake.a searched more than once \(items 0, 1\)"):
        specs_from_config(d, items, prefix="piston_intake.", where="b.yaml")
    cfg = [{"name": "a", "bounds": [60.0, 600.0]}, {"name": "c", "bounds": [-90.0, -10.0]}]
    merged = _merge_items(cfg, [{"key": "piston_intake.a", "bounds": [50.0, 500.0]}], "piston_intake.")
    assert merged == [{"name": "c", "bounds": [-90.0, -10.0]}, {"key": "piston_intake.a", "bounds": [50.0, 500.0]}]
    specs_from_config(d, merged, prefix="piston_intake.", where="b.yaml")  # one gene each
    # another valve's `a` is another parameter: it replaces nothing of this fit's
    other = _merge_items(cfg, [{"key": "piston_rebound.a", "bounds": [50.0, 500.0]}], "piston_intake.")
    assert other == [*cfg, {"key": "piston_rebound.a", "bounds": [50.0, 500.0]}]


def test_a_compliance_current_against_the_records_is_refused_before_the_fit(tmp_path, capsys):
    from test_reliability_io import mono
    data = write_frame(tmp_path / "c.parquet", mono(T=0.5), {"synthetic": True})
    out = tmp_path / "o"
    assert main(["fit", "compliance", "--data", str(data), "--current", "0.32", "--population", "4",
                 "--generations", "1", "--out", str(out)]) == 2
    assert "run 'I1.6': recorded at 1.6 A; --current 0.32 A" in _err(capsys) and not (out / "fit.json").exists()


def test_a_late_text_cell_in_a_large_csv_is_one_line(tmp_path, capsys):
    """pandas reads a large CSV in chunks and warns (DtypeWarning, two lines) when a late chunk changes a
    column's type; the reader infers over the whole file, so only its own one-line error is printed."""
    n = 300_000
    t = np.arange(n) / 5000.0
    df = pd.DataFrame({"run": "passive", "time [s]": t, "displacement [m]": 0.01 * np.sin(2 * np.pi * 13 * t),
                       "force [N]": (1000 * np.sin(2 * np.pi * 13 * t + 0.3)).astype(object)})
    df.loc[250_000, "force [N]"] = "abc"
    src = tmp_path / "big.csv"
    df.to_csv(src, index=False)
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["kpi", "dyno", str(src)]) == 2
    assert "column 'force [N]' is not numeric" in _err(capsys)  # _err: exactly one line
    assert not [w for w in caught if issubclass(w.category, pd.errors.DtypeWarning)], caught


def test_a_mapping_that_is_a_folder_is_named_as_one(tmp_path, capsys):
    src = _csv_source(tmp_path)
    (tmp_path / "m.yaml").mkdir()
    assert main(["import", str(src), "--map", str(tmp_path / "m.yaml"), "--out", str(tmp_path / "o.parquet")]) == 2
    assert "m.yaml: is a folder; expected a mapping YAML file" in _err(capsys)


def test_a_fit_that_misses_its_record_by_more_than_its_range_is_flagged(tmp_path, capsys):
    """The force column 100x too small (an 8 N 'damper', above the readers' 1 N floor): the GA still ends
    somewhere, but the fit's NRMSE exceeds the record's whole range and the command says so; the record as
    recorded is not flagged."""
    from test_reliability_io import mono
    rec = mono(T=0.5)
    for k, tag in ((1.0, "ok"), (1e-2, "scaled")):
        data = write_frame(tmp_path / f"{tag}.parquet", rec.assign(**{"force [N]": k * rec["force [N]"]}),
                           {"synthetic": True})
        assert main(["fit", "compliance", "--data", str(data), "--current", "1.6", "--population", "4",
                     "--generations", "1", "--out", str(tmp_path / tag)]) == 0
        err = capsys.readouterr().err
        assert ("misses the fitted record by more than its measured range" in err) == (tag == "scaled"), err


def _csv_source(tmp_path):
    src = tmp_path / "s.csv"
    df = device().drop(columns="velocity [m/s]").rename(columns={"time [s]": "t", "displacement [m]": "x",
                                                                 "force [N]": "F"})
    df.assign(I=1.6).to_csv(src, index=False)
    return src


def test_an_import_constant_never_replaces_a_mapped_column(tmp_path, capsys):
    m = tmp_path / "m.yaml"
    m.write_text("synthetic: true\ncolumns:\n  t: {quantity: time, unit: s}\n  x: {quantity: displacement, unit: m}\n"
                 "  F: {quantity: force, unit: N}\n  I: {quantity: current, unit: A}\n"
                 "constants:\n  current: {value: 0, unit: mA}\n")
    out = tmp_path / "o.parquet"
    assert main(["import", str(_csv_source(tmp_path)), "--map", str(m), "--out", str(out)]) == 2
    assert "constant 'current': quantity 'current' is already mapped from column 'I'" in _err(capsys)
    assert not out.exists()


@pytest.mark.parametrize("raw", [b'{"data": [[0, 1], [1, 2]', '{"data": [[0, 1]], "n": "\xe9"}'.encode("latin-1")],
                         ids=["truncated", "latin-1"])
def test_an_unreadable_json_source_is_one_line(tmp_path, capsys, raw):
    src = tmp_path / "s.json"
    src.write_bytes(raw)
    m = tmp_path / "m.yaml"
    m.write_text("synthetic: true\njson: {matrix: data, columns: [t, x]}\ncolumns:\n  t: {quantity: time, unit: s}\n"
                 "  x: {quantity: displacement, unit: m}\n")
    assert main(["import", str(src), "--map", str(m), "--out", str(tmp_path / "o.parquet")]) == 2
    assert f"{src}: not a UTF-8 JSON file" in _err(capsys)


def test_kpi_dyno_on_a_flow_bench_record_and_metadata_that_is_no_object(tmp_path, capsys):
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    from test_reliability_io import flow
    p = write_frame(tmp_path / "piston_intake.parquet", flow("piston_intake"), {"protocol": "flowbench", "synthetic": True})
    assert main(["kpi", "dyno", str(p)]) == 2
    assert "a flowbench record without 'displacement [m]' and 'force [N]'; kpi dyno reads damper records" in _err(capsys)
    t = pa.Table.from_pandas(device(), preserve_index=False)
    q = tmp_path / "listmeta.parquet"
    pq.write_table(t.replace_schema_metadata({b"dampertwin": json.dumps([1, 2]).encode()}), q)
    assert main(["kpi", "dyno", str(q)]) == 2
    assert f"{q}: metadata 'dampertwin' is a JSON list; expected a JSON object" in _err(capsys)


def test_a_top_mount_run_the_record_lacks_is_refused_not_skipped():
    """static.run / runs naming no run of the fitted record: a FitError before the GA (it was ignored,
    and a string of runs matched by substring)."""
    from dampertwin.calibration import component_fits as cf
    from dampertwin.calibration.ga import FitError, GASettings
    from dampertwin.design import load
    from test_reliability_io import ROOT
    f = pd.concat([device().assign(run="static"), device().assign(run="sweep_f10")], ignore_index=True)
    kw = dict(cutoff=500.0, force_bandwidth=None, settings=GASettings(4, 50.0, 1, 10.0), seed=0,
              where_k={"frequencies": [10.0], "amplitude": 1e-4})
    d = load(ROOT / "conf" / "design" / "baseline.yaml")
    items = [{"name": "k0", "window": [0.5, 2.0]}]
    for static, want, needle in (({"run": "nosuch"}, None, "no run 'nosuch'"), ({}, ["sweep_f1"], "no run 'sweep_f1'")):
        with pytest.raises(FitError, match=needle):
            cf.fit_topmount_records(d, [("rec.parquet", f)], items, static=static, want=want, **kw)


@pytest.mark.parametrize("path, value, needle", [
    (("actuator", "delay"), 1.0e6, "benches.actuator.delay: 1000000.0; expected 0 to 0.05"),
    (("actuator", "gain"), 1.0e9, "benches.actuator.gain"),
    (("temperature", "start"), 1.0e6, "benches.temperature.start"),
    (("temperature", "drift"), -1.0e6, "benches.temperature.drift"),
    (("noise", "force [N]"), 1.0e12, "benches.noise.force [N]: 1000000000000.0; expected at most 500"),
    (("sensors", "displacement [m]", "resolution"), 1.0, "benches.sensors.displacement [m].resolution"),
    (("nominal",), 5, "nominal: expected a path"),
], ids=["delay", "gain", "temperature", "drift", "noise", "resolution", "nominal"])
def test_a_lab_rig_value_beyond_a_real_rig_is_refused_naming_the_key(tmp_path, path, value, needle):
    """A unit slip in the sample's benches (ms for s, a noise in the wrong unit) is refused when the sample is
    read, naming the key; not a solver failure, nor records the project's reader refuses."""
    import yaml

    from dampertwin.lab import LabError, load_sample
    from test_reliability_io import ROOT
    doc = yaml.safe_load((ROOT / "conf" / "lab" / "sample.yaml").read_text())
    node = doc if path == ("nominal",) else doc["benches"]
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    p = tmp_path / "s.yaml"
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(LabError, match=re.escape(needle)):
        load_sample(p)


def test_param_scale_twice_given_records_and_a_folder_for_a_design_are_one_line(tmp_path, capsys):
    from test_reliability_io import flow
    data = write_frame(tmp_path / "piston_intake.parquet", flow("piston_intake"), {"protocol": "flowbench", "synthetic": True})
    assert main(["fit", "valve", "--valve", "piston_intake", "--data", str(data), "--param", "F_c=1:5:foo",
                 "--out", str(tmp_path / "o")]) == 2
    assert "--param 'F_c=1:5:foo': scale 'foo'; expected" in _err(capsys)
    rec = write_frame(tmp_path / "d.parquet", device(), {"synthetic": True})
    assert main(["fit", "damper", "--data", f"{rec},{tmp_path}/./d.parquet", "--out", str(tmp_path / "o")]) == 2
    assert "given more than once; give each record once" in _err(capsys)
    assert main(["design", "check", str(tmp_path)]) == 2
    assert f"{tmp_path}: a folder; expected a design YAML file" in _err(capsys)


# ------------------------------------------------------------------ the workflow's own settings
@pytest.mark.parametrize("block, key, value, needle", [
    ("decision", "closed_on", "reachd", "decision.closed_on: 'reachd'; expected one of heldout, reached"),
    ("decision", "closd_on", "reached", "decision.closd_on: unknown key (did you mean 'closed_on'?)"),
    ("decision", "min_closed", 1.5, "decision.min_closed: 1.5; expected a number in (0, 1]"),
    ("decision", "partner_resolvable", "yes", "decision.partner_resolvable: 'yes'; expected true or false"),
    ("calibration", "max_param", 3, "profiles.ci.calibration.max_param: unknown key (did you mean 'max_params'?)"),
    ("ci", "bootstrap", 0, "profiles.ci.bootstrap: 0; expected an integer >= 1"),
])
def test_discrepancy_settings_are_checked_before_any_work(tmp_path, monkeypatch, capsys, block, key, value, needle):
    """A misspelt key or a value out of range in conf/discrepancy.yaml was read through a default
    (closed_on: reachd ran the whole-gap gate without a word): now the command stops before reading
    the design, naming the file and the key; the shipped settings pass."""
    import yaml
    from test_reliability_io import ROOT
    doc = yaml.safe_load((ROOT / "conf" / "discrepancy.yaml").read_text())
    where = {"decision": doc["decision"], "ci": doc["profiles"]["ci"],
             "calibration": doc["profiles"]["ci"]["calibration"]}[block]
    where[key] = value
    (tmp_path / "conf").mkdir()
    for marker in ("dvc.yaml", "pyproject.toml"):
        (tmp_path / marker).write_text("")
    (tmp_path / "conf" / "discrepancy.yaml").write_text(yaml.safe_dump(doc))
    monkeypatch.chdir(tmp_path)
    argv = ["discrepancy", "--design", "missing.yaml", "--measured", "m", "--out", "o"]
    assert main(argv) == 2
    err = _err(capsys)
    assert "conf/discrepancy.yaml: invalid settings" in err and needle in err, err
    (tmp_path / "conf" / "discrepancy.yaml").write_text((ROOT / "conf" / "discrepancy.yaml").read_text())
    assert main(argv) == 2  # the shipped settings pass: the next check (the design file) speaks
    assert "missing.yaml: design file not found" in _err(capsys)
