"""Calibration approach 2 (thesis ch. 7, issue 12) end to end on a short
SYNTHETIC damper-level training record made here with the virtual lab
(lab.record on a shortened training protocol), and the table-7.1 / 7.2
conventions."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dampertwin import kpi
from dampertwin.calibration import approach2 as a2
from dampertwin.calibration import sensitivity as sens
from dampertwin.calibration.ga import GASettings
from dampertwin.checkpoint import NpzStore
from dampertwin.design import load, yaml_load_file
from dampertwin.errors import UserError
from dampertwin.protocols import build_runs, load_protocol

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "conf"


# ``short_training`` (a short synthetic damper-level training record): tests/conftest.py


def test_shipped_protocols_for_approach2():
    tr = load_protocol(CONF / "test" / "training.yaml")
    ve = load_protocol(CONF / "test" / "verification.yaml")
    ms = load_protocol(CONF / "test" / "monosine16.yaml")
    assert tr["configuration"] == ve["configuration"] == "damper"
    assert tr["strokes"] == [0.05, 0.03, 0.01] and tr["velocities"] == [0.25, 0.5, 0.75, 1.0]
    assert sorted(tr["currents"]) == sorted(ve["currents"]) == sorted(ms["currents"]) == [0.32, 0.9, 1.6]
    assert ms["configuration"] == "module" and ms["frequency"] == 16.0
    assert 2 * np.pi * ms["frequency"] * ms["amplitude"] == pytest.approx(0.5, rel=0.01)  # 0.5 m/s, 10 mm stroke
    assert {r.name for r in build_runs(ms)} == {"I1.6", "I0.9", "I0.32"}
    from dampertwin.lab import plan  # the lab records all three (one file each, all currents)

    assert {("training", "baseline"), ("verification", "baseline"), ("monosine16", "baseline"),
            ("monosine", "baseline_1.6")} <= set(plan(CONF))


def test_sensitivity_and_concurrent_fit_on_a_lab_record(short_training, tmp_path):
    design = load(CONF / "design" / "baseline.yaml")
    cal = yaml_load_file(CONF / "calibration" / "approach2.yaml")
    rec = a2.check_damper_record(short_training, "training", ["I1.6"])
    st = a2.SensitivitySettings.from_config(cal["sensitivity"], n_base=2)
    prob, res, Y = a2.sensitivity(design, rec, cal, st, seed=4, bandwidth=1000.0, max_wall_s=120, progress=False)
    assert Y.shape == (sens.runs_needed(2, 4), len(prob.measured))
    assert res.groups == list(a2.VALVES) and res.S1.shape == (4, len(prob.measured))
    assert np.all(np.isfinite(res.S1[:, ~res.masked]))
    W = sens.result_weights(res, prob.time, sens.WeightSettings.from_config(cal["weights"]))
    s = GASettings(population=4, reproduction_ratio=75, generations=1, mutation_probability=10, max_wall_s=120)
    fit, prob2 = a2.fit(design, rec, cal, W, res.groups, s, seed=5, bandwidth=1000.0, progress=False,
                        checkpoint=NpzStore(tmp_path / "ck.npz"))
    assert fit.best_objective <= fit.start_objective  # x0 (nominal) is a member: never worse than the drawings
    assert set(fit.best_group_objectives) == {*a2.VALVES, a2.COMPLIANCE}
    assert {"oil.chi", "oil.K_oil", "piston_rebound.a"} <= set(fit.best)
    with pytest.raises(UserError, match="rerun the sensitivity stage"):
        a2.fit(design, rec, cal, W[:3], res.groups[:3], s, seed=5, bandwidth=1000.0, progress=False)


def test_bad_config_names_file_and_key():
    design = load(CONF / "design" / "baseline.yaml")
    cal = yaml_load_file(CONF / "calibration" / "approach2.yaml")
    with pytest.raises(UserError, match="approach2.yaml: valves.piston_x"):
        a2.groups_from_config(design, {**cal, "valves": {"piston_x": "shim"}})
    with pytest.raises(UserError, match="sensitivity: unknown key"):
        a2.SensitivitySettings.from_config({"n_bse": 3})
    with pytest.raises(UserError, match="n_max = 48; expected a power of 2 >= n_base = 16"):
        a2.SensitivitySettings.from_config({**cal["sensitivity"], "n_max": 48}, n_base=16)
    with pytest.raises(UserError, match="n_max = 8"):
        a2.SensitivitySettings.from_config({"n_max": 8}, n_base=16)
    with pytest.raises(UserError, match="tol = 0"):
        a2.SensitivitySettings.from_config({"tol": 0}, n_base=16)
    st = a2.SensitivitySettings.from_config(cal["sensitivity"], n_base=16)
    assert st.n_max == 16 and st.tol == cal["sensitivity"]["tol"]  # no n_max: no doubling
    for name in ("ci", "full", "thesis"):  # every profile's cap is a reachable power of 2 above its n_base
        p2 = yaml_load_file(CONF / "profile" / f"{name}.yaml")["approach2"]["sensitivity"]
        st = a2.SensitivitySettings.from_config({**cal["sensitivity"], "n_max": p2["n_max"]}, n_base=p2["n_base"])
        assert st.n_max > st.n_base
    with pytest.raises(UserError, match="no run"):
        a2.check_damper_record(pd.DataFrame({c: [0.0] for c in a2.DAMPER_COLUMNS}).assign(run="I1.6"), "f", ["I9"])
    t = np.arange(0, 3.0, 0.01)
    two = pd.concat([pd.DataFrame({"time [s]": t, "displacement [m]": 0.0, "force [N]": 0.0, "current [A]": c,
                                   "run": f"I{c:g}"}) for c in (0.9, 1.6)], ignore_index=True)
    tail = a2.check_damper_record(two, "f", None, 1.0)
    n = tail.groupby("run").size()
    assert set(n.index) == {"I0.9", "I1.6"} and n.between(100, 101).all()  # the last 1 s of each run
    assert tail["time [s]"].min() >= 1.98
    with pytest.raises(UserError, match="tail_s"):
        a2.check_damper_record(two, "f", None, -1.0)


def test_table_7_1_and_7_2_conventions_match_the_thesis_rows():
    # thesis table 7.1 row 1 and table 7.2 row 2 (printed values, rounded)
    t71 = kpi.table_7_1([{"no": 1, "current": 1.6, "sim_rebound": 15.8, "meas_rebound": 17.9,
                          "sim_compression": -9.1, "meas_compression": -9.9}])
    assert t71["Rebound difference [%]"].iloc[0] == pytest.approx(11.7, abs=0.2)
    assert t71["Compression difference [%]"].iloc[0] == pytest.approx(-8.1, abs=0.2)  # (m - s) / |m|: printed -7.2
    t72 = kpi.table_7_2([{"no": 2, "current": 0.9, "sim_200": -11.6, "meas_200": -10.4, "sim_300": -18.9,
                          "meas_300": -14.5}])
    assert t72["200 Hz difference [dB]"].iloc[0] == pytest.approx(1.2)
    assert t72["300 Hz difference [dB]"].iloc[0] == pytest.approx(4.4)  # |s - m| (printed 4.3)


def test_input_cutoff_keeps_the_motion_and_is_checked():
    """The training / verification input low-pass must pass the protocols'
    motion (>= 4x its highest fundamental) and filter at all (< 0.45 fs);
    the shipped value does both."""
    cal = yaml_load_file(CONF / "calibration" / "approach2.yaml")
    tr = load_protocol(CONF / "test" / "training.yaml")
    ve = load_protocol(CONF / "test" / "verification.yaml")
    # 1 m/s at 10 mm peak-to-peak: f = v / (pi s) = 31.8 Hz; verification: top band edge 30 Hz
    assert a2.excitation_fundamental(tr) == pytest.approx(1.0 / (np.pi * 0.01))
    assert a2.excitation_fundamental(ve) == 30.0
    c = a2.input_cutoff(cal, {"training": tr, "verification": ve})
    assert 4 * 31.9 <= c < 0.45 * tr["rate"]
    with pytest.raises(UserError, match=r"approach2.yaml: input_cutoff = 100 Hz would filter the training motion"):
        a2.input_cutoff({**cal, "input_cutoff": 100.0}, {"training": tr})
    with pytest.raises(UserError, match="not below 0.45 x the training sampling rate"):
        a2.input_cutoff({**cal, "input_cutoff": 2500.0}, {"training": tr})
    for bad in (-1.0, "200", True, float("nan")):
        with pytest.raises(UserError, match="expected a positive frequency"):
            a2.input_cutoff({**cal, "input_cutoff": bad}, {"training": tr})
