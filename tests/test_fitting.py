"""One-command submodel fits: the friction fit recovers known LuGre
parameters from a SYNTHETIC record (noise added), beats Coulomb + viscous,
reports NRMSE per file and intervals; search bounds from the command line."""

import json
import re

import numpy as np
from scipy import stats
import pandas as pd
import pytest

from dampertwin.cli import main
from dampertwin.cli_fit import parse_param_args
from dampertwin.calibration.ga import FitError
from dampertwin.calibration.uncertainty import gauss_newton_ci
from dampertwin.cli_fit_files import fit_friction
from dampertwin.model.friction_only import lugre_force, simulate_friction
from dampertwin.io import write_frame
from dampertwin.model.rod_friction import lugre, stribeck

TRUE = dict(F_c=20.0, F_s=35.0, k_b=4e5, s2=150.0, c_comp=500.0, vd=0.001, a_s=0.01, alpha_s=2.0)
FIXED = dict(c_comp=500.0, vd=0.001, a_s=0.01, alpha_s=2.0)


def synthetic_record(path, seed=1, f1=0.5, duration=4.0, noise=0.5):
    """A friction-device record from known LuGre parameters (SYNTHETIC)."""
    fs = 2000.0
    t = np.arange(0, duration, 1 / fs)
    x = 0.005 * np.sin(2 * np.pi * f1 * t) + 0.002 * np.sin(2 * np.pi * 1.7 * t)
    F = simulate_friction(t, np.gradient(x, t), **TRUE) + np.random.default_rng(seed).normal(0, noise, len(t))
    write_frame(path, pd.DataFrame({"time [s]": t, "displacement [m]": x, "force [N]": F}),
                {"synthetic": True, "truth": TRUE, "noise [N]": noise})
    return path


def test_keyword_wrapper_matches_positional_lugre():
    dz, F = lugre_force(0.02, 1e-5, **TRUE)
    dz2, F2 = lugre(1e-5, 0.02, TRUE["k_b"], TRUE["F_c"], TRUE["F_s"], TRUE["s2"], TRUE["c_comp"], TRUE["vd"],
                    TRUE["a_s"], TRUE["alpha_s"])
    assert (dz, F) == (dz2, F2)


def test_friction_only_simulation_reaches_the_stribeck_curve():
    t = np.linspace(0, 0.5, 5001)
    for v in (0.003, 0.02, -0.05):
        F = simulate_friction(t, np.full_like(t, v), **TRUE)
        g = stribeck(v, TRUE["F_c"], TRUE["F_s"], TRUE["a_s"], TRUE["alpha_s"])
        assert F[-1] == pytest.approx(np.sign(v) * g + TRUE["s2"] * v, rel=1e-6)


def test_friction_fit_recovers_parameters(tmp_path):
    rec = synthetic_record(tmp_path / "rec.parquet")
    pred = synthetic_record(tmp_path / "pred.parquet", seed=2, f1=0.8, duration=2.0)
    r = fit_friction(rec, fixed=FIXED, predict=[pred], out=tmp_path / "out")
    for k in ("F_c", "F_s", "k_b", "s2"):
        assert r["parameters"][k] == pytest.approx(TRUE[k], rel=0.05), k
        lo, hi = r["uncertainty"]["parameters"][k]["ci95"]
        assert lo < r["parameters"][k] < hi
    assert r["nrmse"] < 0.02
    assert r["files"][str(pred)]["role"] == "predicted" and r["files"][str(pred)]["nrmse"] < 0.03
    assert r["baseline"]["nrmse"] > 5 * r["nrmse"]  # Coulomb + viscous is far worse
    doc = json.loads((tmp_path / "out" / "fit.json").read_text())
    assert doc["parameters"] == pytest.approx(r["parameters"])
    assert list((tmp_path / "out").glob("*.png"))


def test_fit_cli_friction_with_command_line_bounds(tmp_path, capsys):
    rec = synthetic_record(tmp_path / "rec.parquet", duration=2.0)
    bounds = tmp_path / "b.yaml"
    bounds.write_text("fixed: {c_comp: 500.0, vd: 0.001, a_s: 0.01, alpha_s: 2.0, k_b: 4.0e5}\n"
                      "parameters:\n  - {name: F_c, bounds: [0, 100]}\n  - {name: F_s, bounds: [0, 100]}\n")
    out = tmp_path / "o"
    assert main(["fit", "friction", "--data", str(rec), "--out", str(out), "--bounds", str(bounds),
                 "--param", "s2=0:1000"]) == 0
    doc = json.loads((out / "fit.json").read_text())
    assert set(doc["parameters"]) == {"F_c", "F_s", "s2"} and doc["bounds"]["s2"][:2] == [0.0, 1000.0]
    assert doc["parameters"]["F_c"] == pytest.approx(20.0, rel=0.05)
    assert main(["fit", "friction", "--data", str(rec), "--out", str(out), "--param", "mu=0:1"]) == 2
    assert "unknown friction parameter" in capsys.readouterr().err


def test_friction_search_errors_name_their_source(tmp_path, capsys):
    """An item the friction fit refuses is named with where it came from: the --bounds file, --param."""
    rec = synthetic_record(tmp_path / "rec.parquet", duration=2.0)
    bounds = tmp_path / "b.yaml"
    bounds.write_text("parameters:\n  - {name: F_c, bounds: [100, 0]}\n")
    out = tmp_path / "o"
    assert main(["fit", "friction", "--data", str(rec), "--out", str(out), "--bounds", str(bounds)]) == 2
    assert f"{bounds}: item 0 (F_c): bad interval" in capsys.readouterr().err
    assert main(["fit", "friction", "--data", str(rec), "--out", str(out), "--param", "mu=0:1"]) == 2
    assert "--param: item 0 (" in capsys.readouterr().err
    bounds.write_text("parameters:\n  - {name: F_c, bounds: [0, 100]}\n")
    assert main(["fit", "friction", "--data", str(rec), "--out", str(out), "--bounds", str(bounds),
                 "--param", "mu=0:1"]) == 2
    assert f"{bounds} + --param: item 1 (" in capsys.readouterr().err
    assert not out.exists()


def test_param_args_and_errors():
    assert parse_param_args(["F_c=0:50", "top_mount.k0=1e3:1e6:log"]) == [
        {"name": "F_c", "bounds": [0.0, 50.0], "scale": "lin"},
        {"key": "top_mount.k0", "bounds": [1e3, 1e6], "scale": "log"}]
    with pytest.raises(FitError, match="F_c=abc"):
        parse_param_args(["F_c=abc"])


def test_gauss_newton_interval_on_linear_model():
    """For y = a x + noise the interval equals ordinary least squares'."""
    x = np.linspace(0, 1, 400)
    y = 2.0 * x + np.random.default_rng(5).normal(0, 0.1, 400)
    a = float(np.dot(x, y) / np.dot(x, x))
    r = a * x - y
    ci = gauss_newton_ci(x[:, None], r, ["a"], np.array([a]))
    se = np.sqrt(np.dot(r, r) / (400 - 1) / np.dot(x, x))
    p = ci["parameters"]["a"]
    assert p["std"] == pytest.approx(se, rel=0.1)
    t = stats.t.ppf(0.975, ci["n_eff"] - 1)  # Student-t interval on the effective sample size
    assert p["ci95"] == pytest.approx([a - t * p["std"], a + t * p["std"]], rel=1e-9)
    assert p["determined"] and ci["undetermined"] == []
    assert abs(a - 2.0) < p["ci95"][1] - a  # the true slope lies inside


def test_study_report_flags_and_html(tmp_path):
    import shutil

    from conftest import ROOT
    from dampertwin.study_report import _flag_rows, build_report

    src = ROOT / "results" / "approach1"
    for f in ("table_6_5.parquet", "table_6_6.parquet", "fits.json", "metrics.json"):
        shutil.copy(src / f, tmp_path / f)
    fits = json.loads((tmp_path / "fits.json").read_text())
    name = next(iter(fits["fits"]))
    key, key2 = list(fits["fits"][name]["values"])[:2]
    fits["fits"][name]["uncertainty"] = {"parameters": {
        key: {"value": 1.0, "ci95": [-2.0, 4.0], "rel_halfwidth": 3.0, "determined": False,
              "why": "CI half-width 300% of value"},
        key2: {"value": 1.0, "ci95": [0.9, 1.1], "rel_halfwidth": 0.1, "determined": True, "why": ""}}}
    fits["fits"][name]["determined"] = {"quantity": "valve lift-force curve F_k(x), eq. 4.19",
                                        "curve": [{"lift [m]": 1e-4, "force [N]": 512.0, "ci95 low [N]": 500.0,
                                                   "ci95 high [N]": 524.0, "rel. half-width [%]": 2.34}]}
    fits["fits"][name]["bound_hits"] = [{"parameter": key, "bound": "upper", "value": 2.0, "limit": 2.0,
                                         "kind": "search"}]
    (tmp_path / "fits.json").write_text(json.dumps(fits))
    # cells well beyond, just beyond and just inside the flag threshold, whatever the committed study says
    t65 = pd.read_parquet(tmp_path / "table_6_5.parquet")
    lim = json.loads((tmp_path / "metrics.json").read_text())["flags"]["thresholds"]["percent"]
    cols = [c for c in t65.columns if c.endswith("diff [%]")]
    t65.loc[t65.index[0], cols[0]] = lim + 10.0
    t65.loc[t65.index[1], cols[-1]] = -(lim - 0.5)
    t65.loc[t65.index[2], cols[1]] = lim + 0.5
    t65.to_parquet(tmp_path / "table_6_5.parquet")
    import base64

    png = b"\x89PNG\r\n\x1a\n" + b"0" * 32  # bytes to embed (content is not decoded)
    (tmp_path / "plots" / "baseline_1.6").mkdir(parents=True)
    (tmp_path / "plots" / "baseline_1.6" / "monosine.png").write_bytes(png)
    md, html = build_report(tmp_path, measured_label="test data", cases=["baseline_1.6"])
    text = md.read_text()
    n = len(fits["fits"][name]["values"])
    assert "## Flags" in text
    flags = text.split("## Flags")[1].split("\n## ")[0]
    fam = name.split("/")[0]
    assert re.search(rf"\| {fam} \(\d+ fits?\) \| parameters not determined \| [^|]*\b{key.split('.')[-1]}\b", flags)
    assert f"| {name} | ends on a search bound | {key.split('.')[-1]} = 2 at its upper bound 2:" in flags
    assert f"1 of {n} parameters" not in flags  # one row per fit family, not one per fit
    # a short table, not a wall of text: one row per KPI table with flags, one per fit family with
    # undetermined parameters, one per fit on a bound, failing or not lowering its objective
    rows = [ln for ln in flags.splitlines() if ln.startswith("| ") and not ln.startswith("| where |")]
    fam = {n.split("/")[0] for n, f in fits["fits"].items() if any(
        not u["determined"] for k, u in ((f.get("uncertainty") or {}).get("parameters", {})).items() if k in f["values"])}
    per_fit = sum(bool(f.get("bound_hits")) + bool(f.get("failed_simulations"))
                  + (f["objective_best"] >= f["objective_start"]) for f in fits["fits"].values())
    t66 = pd.read_parquet(tmp_path / "table_6_6.parquet")
    db = json.loads((tmp_path / "metrics.json").read_text())["flags"]["thresholds"]["dB"]
    kpi_rows = 1 + bool((t66[[c for c in t66.columns if c.endswith("diff [dB]")]].abs() > db).any().any())
    assert len(rows) == kpi_rows + len(fam) + per_fit, rows
    det = text.split("## What the data determine")[1].split("\n## ")[0]
    assert f"### {name}: valve lift-force curve" in det and "| 0.1 | 512 | [500, 524] | 2.34 |" in det
    # every table-6.5 cell beyond the threshold compare used is flagged, and no other (the layout has
    # max and min per half-cycle since issue 14); the flag table has one row for them with the worst cell
    _, row_flags = _flag_rows(t65, cols, lim, "%")
    for _, r in t65.iterrows():
        where = f"{r['Design case']}, {float(r['Active valve current [A]']):g} A"
        row = next((f["detail"] for f in row_flags if f["where"] == where), "")
        for c in cols:
            assert (f"{c} {float(r[c]):+.2f}" in row) == (abs(float(r[c])) > lim), (r, c)
    worst = max(((abs(float(r[c])), f"{r['Design case']}, {float(r['Active valve current [A]']):g} A, {c} "
                  f"{float(r[c]):+.2f}") for _, r in t65.iterrows() for c in cols))[1]
    assert f"| table 6.5 | {len(row_flags)} of {len(t65)} cases abs. diff > {lim:g} % | worst: {worst};" in flags
    assert "![baseline_1.6 monosine](plots/baseline_1.6/monosine.png)" in text
    h = html.read_text()
    assert "<table>" in h
    # self-contained: the PNG present is embedded, the absent one named, nothing links out
    assert f'<img src="data:image/png;base64,{base64.b64encode(png).decode()}"' in h
    assert "image not available: plots/baseline_1.6/psd.png" in h
    assert not re.search(r'<img src="(?!data:)', h)


def test_fit_cli_valve_reports_nrmse_and_intervals(tmp_path):
    """A valve fit on a flow-bench record simulated from the baseline with a
    changed stiffness (SYNTHETIC): fit.json carries NRMSE per file, the
    objective and an interval per parameter; the GA lowers the objective."""
    from conftest import BASELINE
    from dampertwin.design import load
    from dampertwin.excitation import Excitation
    from dampertwin.simulation import simulate

    d = load(BASELINE)
    t = np.arange(0, 2.001, 1e-3)
    q = 20.0 / 60000.0 * np.interp(t, [0, 1.0, 2.001], [0.0, 1.0, 0.0])
    ex = Excitation.from_samples(t, q, kind="flow")
    r = simulate(d.with_overrides({"piston_intake.a": 260.0}), ex, "valve", bench_valve="piston_intake", rate=1000.0)
    f = r.to_frame()
    rec = write_frame(tmp_path / "pi.parquet", pd.DataFrame(
        {"time [s]": t, "flow [m^3/s]": q, "dp [Pa]": (f["p upstream [Pa]"] - f["p downstream [Pa]"]).to_numpy()[:len(t)],
         "run": "piston_intake"}),
        {"synthetic": True})
    out = tmp_path / "fit"
    assert main(["fit", "valve", "--valve", "piston_intake", "--data", str(rec), "--out", str(out),
                 "--param", "a=100:400", "--population", "6", "--generations", "3", "--predict", str(rec)]) == 0
    doc = json.loads((out / "fit.json").read_text())
    assert set(doc["parameters"]) == {"piston_intake.a"}
    assert doc["objective"]["best"] < doc["objective"]["start"]
    assert abs(doc["parameters"]["piston_intake.a"] - 260.0) < abs(200.0 - 260.0)
    assert doc["files"][str(rec)]["nrmse"] < 0.05
    u = doc["uncertainty"]["parameters"]["piston_intake.a"]
    assert u["ci95"][0] < doc["parameters"]["piston_intake.a"] < u["ci95"][1]
    assert list(out.glob("valve_*.png"))


def test_fit_valve_with_a_complete_bounds_file_needs_no_repository(tmp_path, monkeypatch):
    """The shipped example conf/fit/valve_piston_intake.yaml gives the search, input_cutoff and objective:
    run outside a repository with it and --design, the fit needs nothing of conf/calibration (it read
    conf/calibration/valves.yaml for defaults the file had given, and refused); without the objective the
    refusal names the key to give."""
    import shutil
    from pathlib import Path

    from conftest import BASELINE, ROOT
    from dampertwin.design import load
    from dampertwin.excitation import Excitation
    from dampertwin.simulation import simulate

    t = np.arange(0, 2.001, 1e-3)
    q = 20.0 / 60000.0 * np.interp(t, [0, 1.0, 2.001], [0.0, 1.0, 0.0])
    r = simulate(load(BASELINE), Excitation.from_samples(t, q, kind="flow"), "valve", bench_valve="piston_intake",
                 rate=1000.0).to_frame()
    rec = write_frame(tmp_path / "pi.parquet", pd.DataFrame(
        {"time [s]": t, "flow [m^3/s]": q, "dp [Pa]": (r["p upstream [Pa]"] - r["p downstream [Pa]"]).to_numpy()[:len(t)],
         "run": "piston_intake"}), {"synthetic": True})
    (tmp_path / "d").mkdir()
    design = Path(shutil.copy(BASELINE, tmp_path / "d"))
    shutil.copy(ROOT / "conf" / "design" / "active_valve_baseline.csv", tmp_path / "d")
    bounds = tmp_path / "b.yaml"
    shutil.copy(ROOT / "conf" / "fit" / "valve_piston_intake.yaml", bounds)
    monkeypatch.chdir(tmp_path)
    argv = ["fit", "valve", "--valve", "piston_intake", "--data", str(rec), "--bounds", str(bounds), "--design",
            str(design), "--population", "4", "--generations", "1", "--out"]
    assert main([*argv, str(tmp_path / "fit")]) == 0
    bounds.write_text("".join(x for x in bounds.read_text().splitlines(True) if not x.startswith("objective:")))
    with pytest.raises(FitError, match="no objective in --bounds given and no dampertwin repository here"):
        from dampertwin.cli_fit import run_fit_cli
        from dampertwin.cli import build_parser
        run_fit_cli(build_parser().parse_args([*argv, str(tmp_path / "fit2")]))


def _top_mount_record(tmp_path, offset: float, design_overrides: dict):
    """A top-mount record simulated from the baseline (SYNTHETIC): 2 s of a
    5 Hz + 60 Hz displacement, force through the documented 1 kHz load cell
    plus a zero offset [N]."""
    from conftest import BASELINE
    from dampertwin.design import load
    from dampertwin.excitation import Excitation
    from dampertwin.sensors import sensor_lowpass
    from dampertwin.simulation import simulate

    fs = 5000.0
    t = np.arange(0, 2.0 + 0.5 / fs, 1 / fs)
    x = 5e-4 * np.sin(2 * np.pi * 5 * t) * np.minimum(t / 0.2, 1) + 2e-5 * np.sin(2 * np.pi * 60 * t)
    ex = Excitation.from_samples(t, x)
    r = simulate(load(BASELINE).with_overrides(design_overrides), ex, "topmount", rate=fs)
    F = sensor_lowpass(r.to_frame()["top mount force [N]"].to_numpy()[:len(t)], 1000.0, fs) + offset
    return write_frame(tmp_path / "tm.parquet", pd.DataFrame({"time [s]": t, "displacement [m]": x, "force [N]": F,
                                                             "run": "random"}),
                       {"synthetic": True})


def test_fit_cli_top_mount_fits_the_load_cell_zero(tmp_path):
    """The bench's load-cell zero is a fitted nuisance (issue 14): a record
    with a 6 N offset and a 20 % stiffer k0 gives back the offset and k0;
    the design overlay carries no sensor.* key."""
    rec = _top_mount_record(tmp_path, 6.0, {"top_mount.k0": 1.44e6})
    out = tmp_path / "fit"
    assert main(["fit", "topmount", "--data", str(rec), "--out", str(out), "--param", "k0=6e5:2.4e6:log",
                 "--param", "sensor.force_offset=-20:20", "--population", "16", "--generations", "20"]) == 0
    doc = json.loads((out / "fit.json").read_text())
    assert doc["parameters"]["sensor.force_offset"] == pytest.approx(6.0, abs=1.5)
    assert doc["parameters"]["top_mount.k0"] == pytest.approx(1.44e6, rel=0.05)
    assert not any(k.startswith("sensor.") for k in doc["overrides"])
    # what the record determines: the dynamic stiffness at the documented sweep frequencies, whose band
    # holds the true mount's
    from conftest import BASELINE
    from dampertwin.calibration.identifiability import top_mount_dynamic_stiffness
    from dampertwin.design import load

    rows = doc["determined"]["rows"]
    assert [r["frequency [Hz]"] for r in rows][:3] == [1.0, 2.0, 5.0]
    true = top_mount_dynamic_stiffness(load(BASELINE).with_overrides({"top_mount.k0": 1.44e6}), {}, [],
                                       np.zeros((0, 0)), 10.0, [1.0, 5.0, 20.0], rows[0]["amplitude [m]"])
    for tr in true:
        r = next(r for r in rows if r["frequency [Hz]"] == tr["frequency [Hz]"])
        lo, hi = r["stiffness ci95 [N/m]"]
        assert lo <= tr["stiffness [N/m]"] <= hi and hi - lo < 0.3 * tr["stiffness [N/m]"]


def test_fit_cli_top_mount_default_search_space_runs(tmp_path):
    """Without --bounds / --param the study's search space (with its
    sensor.* nuisance keys) is used: it must run, not refuse the bandwidth."""
    rec = _top_mount_record(tmp_path, 0.0, {})
    out = tmp_path / "fit"
    assert main(["fit", "topmount", "--data", str(rec), "--out", str(out), "--population", "4",
                 "--generations", "1"]) == 0
    doc = json.loads((out / "fit.json").read_text())
    assert {"sensor.force_delay", "sensor.force_offset", "top_mount.k1"} <= set(doc["parameters"])


def test_static_curve_drops_the_bench_zero():
    """thesis 7.2 least-squares curve with the bench's zero: a cubic curve
    plus a 5 N offset gives back the cubic (no even terms bent to absorb it)."""
    from dampertwin.calibration.approach1 import fit_static_curve

    X = 1.5e-3 * np.sin(np.linspace(0, 2 * np.pi, 801))
    F = 8e5 * X + 9e10 * X**3 + 5.0
    c = fit_static_curve(pd.DataFrame({"run": "static", "displacement [m]": X, "force [N]": F}), "static", 5)
    assert c[0] == pytest.approx(8e5, rel=1e-6) and c[2] == pytest.approx(9e10, rel=1e-6)
    assert abs(c[1]) * 1.5e-3**2 < 1e-6 and abs(c[3]) * 1.5e-3**4 < 1e-6


def test_static_curve_subtracts_the_rubber_hysteresis():
    """A 0.025 Hz triangle on the baseline top mount (SYNTHETIC) still holds
    the rubber's relaxation forces: plain least squares flattens the cubic
    term; with the modelled dynamics subtracted the design's curve returns."""
    from conftest import BASELINE
    from dampertwin.calibration.approach1 import fit_static_curve
    from dampertwin.design import load
    from dampertwin.excitation import Excitation
    from dampertwin.simulation import simulate

    d = load(BASELINE)
    fs = 200.0
    t = np.arange(0, 40.0 + 0.5 / fs, 1 / fs)
    x = 1.5e-3 * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * t / 40.0))
    F = simulate(d, Excitation.from_samples(t, x), "topmount", rate=fs).to_frame()["top mount force [N]"].to_numpy()
    rec = pd.DataFrame({"run": "static", "time [s]": t, "displacement [m]": x, "force [N]": F[:len(t)] + 4.0})
    true = list(d["top_mount.F_LD"])
    plain = fit_static_curve(rec, "static", 5)
    corrected = fit_static_curve(rec, "static", 5, d, 20.0)
    assert abs(plain[2] / true[2] - 1) > 0.1
    assert corrected[2] == pytest.approx(true[2], rel=0.02) and corrected[0] == pytest.approx(true[0], rel=0.01)


def test_sensor_delay_shifts_a_sine_by_the_delay():
    """sensors.sensor_delay: a 300 Hz sine at 5 kHz, 0.17 ms (0.85 samples)
    later, equals the analytic delayed sine to 0.2 % of its amplitude;
    a negative delay advances it."""
    from dampertwin.sensors import sensor_delay

    fs, f = 5000.0, 300.0
    t = np.arange(0, 0.2, 1 / fs)
    x = np.sin(2 * np.pi * f * t)
    inner = slice(10, -10)
    for d in (1.7e-4, -2.3e-4):
        y = sensor_delay(x, d, fs)
        assert np.max(np.abs(y[inner] - np.sin(2 * np.pi * f * (t[inner] - d)))) < 2e-3
    assert sensor_delay(x, 0.0, fs) is x


def test_fit_valve_gives_the_study_stage_result(tmp_path):
    """`dampertwin fit valve --profile ci` and the study's flow-bench stage
    (calibration.approach1.fit_valve with the stage's arguments: the
    valves.yaml search space, the profile's GA and polish budgets, the
    documented bench) give the same values and objective, bit for bit, on
    the same record and seed (SYNTHETIC record: baseline with a stiffer
    intake valve)."""
    from conftest import BASELINE, ROOT
    from dampertwin.calibration.approach1 import fit_valve
    from dampertwin.calibration.ga import GASettings
    from dampertwin.calibration.polish import PolishSettings
    from dampertwin.design import load, yaml_load_file
    from dampertwin.excitation import Excitation
    from dampertwin.io import read_frame
    from dampertwin.protocols import load_protocol
    from dampertwin.simulation import simulate

    d = load(BASELINE)
    t = np.arange(0, 2.001, 1e-3)
    q = 25.0 / 60000.0 * np.interp(t, [0, 1.0, 2.001], [0.0, 1.0, 0.0])
    r = simulate(d.with_overrides({"piston_intake.a": 1.3 * d["piston_intake.a"]}),
                 Excitation.from_samples(t, q, kind="flow"), "valve", bench_valve="piston_intake", rate=1000.0)
    f = r.to_frame()
    rec = write_frame(tmp_path / "pi.parquet", pd.DataFrame(
        {"time [s]": t, "flow [m^3/s]": q, "dp [Pa]": (f["p upstream [Pa]"] - f["p downstream [Pa]"]).to_numpy()[:len(t)],
         "run": "piston_intake"}),
        {"synthetic": True})
    prof = yaml_load_file(ROOT / "conf" / "profile" / "ci.yaml")
    fb = load_protocol(ROOT / "conf" / "test" / "flowbench.yaml")
    study = fit_valve(d, "piston_intake", read_frame(rec, "flowbench")[0],
                      yaml_load_file(ROOT / "conf" / "calibration" / "valves.yaml"),
                      GASettings.from_config(prof["ga"]["valves"]), 7,
                      bench={"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]},
                      progress=False, polish_settings=PolishSettings.from_config(prof["polish"]))
    out = tmp_path / "fit"
    assert main(["fit", "valve", "--valve", "piston_intake", "--data", str(rec), "--out", str(out),
                 "--design", str(BASELINE), "--profile", "ci", "--seed", "7"]) == 0
    doc = json.loads((out / "fit.json").read_text())
    assert study.polish and doc["polish"]["objective_polished"] == study.best_objective
    assert doc["parameters"] == study.best
    assert doc["objective"]["best"] == study.best_objective
