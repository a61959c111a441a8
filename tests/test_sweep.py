"""Hydra OFAT sweeps: artifacts, failure isolation, resume, summary."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dampertwin.io import read_frame, read_meta
from dampertwin.sweep import COMPLETE, FAILED, trend_agreement

from conftest import ROOT


def sweep(tmp: Path, *args: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "dampertwin.cli", "sweep", f"results_dir={tmp}", "sweep=t", "tests=[monosine]",
           "use_calibrated=false", *args]
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=dict(os.environ, MPLBACKEND="Agg"))
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-4000:]
    return r


@pytest.fixture(scope="module")
def two_variants(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sweeps")
    r = sweep(tmp, "variant=baseline_1.6,lower_base_intake", "fail_on=lower_base_intake")
    return tmp / "t", r


@pytest.mark.slow  # a Hydra multirun
def test_two_variant_sweep_writes_artifacts_with_metadata(two_variants):
    d, _ = two_variants
    base = d / "baseline_1.6"
    assert (base / COMPLETE).is_file()
    df, meta = read_frame(base / "monosine.parquet", "monosine")
    assert len(df) > 1000 and "rod acceleration [m/s^2]" in df
    assert meta["variant"] == "baseline_1.6" and meta["design_hash"] and meta["config_hash"]
    assert meta["config"]["variant"]["case"] == "baseline_1.6" and meta["config"]["tests"] == ["monosine"]
    k = pd.read_parquet(base / "kpis.parquet")
    assert np.isfinite(k["rebound peak [g]"].iloc[0]) and k["compression peak [g]"].iloc[0] < 0


@pytest.mark.slow  # a Hydra multirun
def test_failing_variant_is_reported_and_others_complete(two_variants):
    d, r = two_variants
    failed = json.loads((d / "lower_base_intake" / FAILED).read_text())
    assert "deliberate failure" in failed["error"]
    assert not (d / "lower_base_intake" / COMPLETE).exists()
    tab = pd.read_parquet(d / "summary.parquet")
    st = dict(zip(tab.variant, tab.status))
    assert st["baseline_1.6"] == "ok" and st["lower_base_intake"].startswith("failed")
    assert "FAILED" in r.stdout + r.stderr


@pytest.mark.slow  # a Hydra multirun
def test_rerun_skips_completed_and_retries_failed(two_variants):
    d, _ = two_variants
    before = (d / "baseline_1.6" / "monosine.parquet").stat().st_mtime_ns
    r = sweep(d.parent, "variant=baseline_1.6,lower_base_intake")
    assert (d / "baseline_1.6" / "monosine.parquet").stat().st_mtime_ns == before
    assert "baseline_1.6: complete, skipped" in r.stdout + r.stderr
    assert (d / "lower_base_intake" / COMPLETE).is_file()  # retried, now without the forced failure
    # the attempt count goes on past a success: a later failure of this variant is never taken for the
    # earlier run's record (sweep.summarize's `before`)
    assert json.loads((d / "lower_base_intake" / COMPLETE).read_text())["attempt"] == 2
    assert json.loads((d / "baseline_1.6" / COMPLETE).read_text())["attempt"] == 1
    tab = pd.read_parquet(d / "summary.parquet")
    assert set(tab.status) == {"ok"}
    row = tab.set_index("variant").loc["lower_base_intake"]
    assert row["change rebound peak [g]"] == pytest.approx(row["rebound peak [g]"] -
                                                            tab.set_index("variant").loc["baseline_1.6", "rebound peak [g]"])


@pytest.mark.slow  # a Hydra multirun
def test_generic_ofat_factor_levels(tmp_path):
    sweep(tmp_path, "factor=base_intake.a", "level=-0.2,0.2")
    d = tmp_path / "t"
    names = sorted(p.name for p in d.iterdir() if p.is_dir() and not p.name.startswith("."))
    assert names == ["baseline_1.6__base_intake.a@+20%", "baseline_1.6__base_intake.a@-20%"]
    hashes = {read_meta(d / n / "kpis.parquet")["design_hash"] for n in names}
    assert len(hashes) == 2
    cfg = read_meta(d / names[0] / "kpis.parquet")["config"]
    assert cfg["factor"] == "base_intake.a" and cfg["level"] == 0.2


def test_trend_agreement_counts_directions():
    tab = pd.DataFrame({"case": ["baseline_1.6", "lower_base_intake", "alternative_top_mount"], "factor": ["", "", ""],
                        "|rebound| trend": [0, 1, 1], "|rebound| trend thesis": [0, 1, -1],
                        "|compression| trend": [0, -1, 1], "|compression| trend thesis": [0, -1, 1]})
    assert trend_agreement(tab) == (3, 4)


def test_c_params_ofat_config_lists_every_scalar_c_parameter():
    from dampertwin.design import load, yaml_load

    d = load(ROOT / "conf" / "design" / "baseline.yaml")
    cfg = yaml_load((ROOT / "conf" / "ofat" / "c_params.yaml").read_text())
    listed = cfg["hydra"]["sweeper"]["params"]["factor"].split(",")
    assert listed == [p.key for p in d.by_type("C") if not isinstance(p.value, tuple)]



def test_trend_table_reasons_are_derived_not_assumed():
    """Directions vs thesis table 6.5 (baseline |rebound| 10.7, |compression|
    9.2 g): each disagreement gets the reason its numbers support."""
    from dampertwin.sweep import trend_metrics, trend_table

    tab = pd.DataFrame({"case": ["baseline_1.6", "lower_base_intake", "lower_base_compression", "increased_precharge"],
                        "factor": ["", "", "", ""], "status": ["ok"] * 4,
                        "rebound peak [g]": [4.0, 5.0, 3.0, 4.02],        # thesis: up, down, down
                        "compression peak [g]": [-9.0, -9.5, -8.0, -9.3]})  # thesis: down, down, up
    lab = {"baseline_1.6": (3.5, -9.0), "lower_base_intake": (4.5, -8.0), "lower_base_compression": (3.0, -9.0),
           "increased_precharge": (3.6, -8.5)}
    tr = trend_table(tab, lab).set_index(["case", "half-cycle"])
    assert tr.loc[("lower_base_intake", "rebound"), "agrees"]
    assert tr.loc[("lower_base_compression", "rebound"), "agrees"]
    # compression of lower_base_intake: model up (+0.5), thesis down (-0.8), lab down (-1.0): model side
    assert tr.loc[("lower_base_intake", "compression"), "reason"].startswith("model defect")
    # compression of lower_base_compression: model down, thesis down -> agrees
    assert tr.loc[("lower_base_compression", "compression"), "agrees"]
    # rebound of increased_precharge: +0.02 g simulated, thesis -0.5 g: no direction
    assert "below the 0.1 g resolution" in tr.loc[("increased_precharge", "rebound"), "reason"]
    # compression of increased_precharge: model up 0.3, thesis up 0.3 -> agrees
    assert tr.loc[("increased_precharge", "compression"), "agrees"]
    tab.loc[3, "rebound peak [g]"] = 4.5  # model up, thesis down, lab up: the lab part's physics
    lab["increased_precharge"] = (4.0, -9.05)  # and compression: model up 0.3, thesis up 0.3, lab 0.05
    tab.loc[3, "compression peak [g]"] = -8.5  # model now down: lab has no direction -> unexplained
    raw = trend_table(tab, lab)
    tr2 = raw.set_index(["case", "half-cycle"])
    assert tr2.loc[("increased_precharge", "rebound"), "reason"].startswith("lab sample physics")
    assert tr2.loc[("increased_precharge", "compression"), "reason"] == "unexplained"
    m = trend_metrics(raw)
    assert m["compared"] == len(tr2) and m["agree"] == int(tr2.agrees.sum()) == 3
    assert {(d["case"], d["half-cycle"]) for d in m["disagreeing"]} == set(tr2.index[~tr2.agrees])


def test_trend_against_the_thesis_simulated_column():
    """Issue 40 item 4: directions of |peak| change vs the thesis' SIMULATED table-6.5 column
    (baseline 8.1 / -16.9 g): counted where the thesis' change has a direction, a change here
    below 0.1 g or the other way round disagrees, with its reason."""
    from dampertwin.sweep import simulated_trend_table, trend_metrics

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "stages"))
    from sweep import thesis_simulated

    ts = thesis_simulated(Path(__file__).resolve().parents[1] / "conf" / "thesis" / "published.yaml")
    assert ts["baseline_1.6"] == (8.1, -16.9) and ts["lower_base_intake"] == (13.7, -16.1)
    tab = pd.DataFrame({"case": ["baseline_1.6", "lower_base_intake", "increased_precharge", "different_active_valve"],
                        "factor": ["", "", "", ""], "status": ["ok"] * 4,
                        # thesis' model: rebound up 5.6 / up 1.9 / up 0.2, |compression| down 0.8 / 0.3 / 0.6
                        "rebound peak [g]": [5.0, 6.0, 4.0, 5.05],
                        "compression peak [g]": [-10.0, -9.0, -10.5, -9.5]})
    tr = simulated_trend_table(tab, ts).set_index(["case", "half-cycle"])
    assert len(tr) == 6
    assert tr.loc[("lower_base_intake", "rebound"), "agrees"] and tr.loc[("lower_base_intake", "compression"), "agrees"]
    assert not tr.loc[("increased_precharge", "rebound"), "agrees"]  # down here, up there
    assert tr.loc[("increased_precharge", "rebound"), "reason"].startswith("opposite direction")
    assert not tr.loc[("increased_precharge", "compression"), "agrees"]  # |peak| up 0.5 here, down 0.3 there
    assert "below the 0.1 g resolution" in tr.loc[("different_active_valve", "rebound"), "reason"]
    assert tr.loc[("different_active_valve", "compression"), "agrees"]
    m = trend_metrics(tr.reset_index())
    assert (m["agree"], m["compared"]) == (3, 6)


def test_job_names_of_distinct_levels_differ():
    """Each OFAT level gets its own folder: levels 0.3 % apart never share one (they did when the
    name rounded the level to whole percent); round levels keep their short names."""
    from omegaconf import OmegaConf

    from dampertwin.sweep import job_name

    def name(level):
        return job_name(OmegaConf.create({"variant": {"case": "baseline_1.6"}, "factor": "piston_intake.a",
                                          "level": level}))

    assert name(0.2) == "baseline_1.6__piston_intake.a@+20%" and name(-0.2) == "baseline_1.6__piston_intake.a@-20%"
    levels = [0.001, 0.004, 0.0041, 0.2, 0.21, -0.001]
    assert len({name(v) for v in levels}) == len(levels)
    assert name(0.001) == "baseline_1.6__piston_intake.a@+0.1%"
