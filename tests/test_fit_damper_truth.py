"""`dampertwin fit damper` on the virtual laboratory's twin-tube sample (lab 3: the truth, other physics than the
model: plate-bending shim stacks, Murnaghan oil, gas dissolution and heat exchange, ...), dyno records at three
clicker settings: fitted on one, the others predicted from their settings alone. SYNTHETIC records."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dampertwin import cli
from dampertwin.design import load
from dampertwin.io import write_frame
from dampertwin.lab import load_sample
from dampertwin.lab_passive import measure_excitation
from dampertwin.protocols import build_runs, load_protocol

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "conf" / "lab" / "twin_tube_sample.yaml"
SETTINGS = {"fit": {"rebound": 3, "compression": 2}, "soft": {"rebound": 6, "compression": 4},
            "hard": {"rebound": 0, "compression": 0}}


@pytest.mark.slow
def test_fit_damper_on_the_truth_predicts_other_clicker_settings(tmp_path):
    base = load(ROOT / "conf" / "design" / "twin_tube.yaml")
    run = build_runs(load_protocol(ROOT / "conf" / "test" / "dyno.yaml"))[0]
    doc = load_sample(SAMPLE)
    files = {}
    for tag, clicks in SETTINGS.items():  # the hidden damper at each setting: its drawings at those clicks
        design = base.at_setting(clicks).dump(tmp_path / f"design_{tag}.yaml")
        df, meta = measure_excitation(dict(doc, nominal=str(design), _path=str(SAMPLE)), run.excitation,
                                      name="passive", test="dyno", rate=1000.0)
        files[tag] = write_frame(tmp_path / f"{tag}.parquet", df, {**meta, "setting": clicks})
    out = tmp_path / "fit"
    assert cli.main(["fit", "damper", "--design", str(ROOT / "conf" / "design" / "twin_tube.yaml"),
                     "--data", str(files["fit"]), "--predict", str(files["soft"]), str(files["hard"]),
                     "--out", str(out), "--population", "16", "--generations", "10"]) == 0
    res = json.loads((out / "fit.json").read_text())
    nrmse = {tag: res["files"][str(p)]["nrmse"] for tag, p in files.items()}
    # measured 2026-11-27: fitted 0.032, predicted 0.024 (soft) / 0.042 (hard); the design's own values
    # give an objective 1.5x the fitted one
    assert nrmse["fit"] < 0.05 and nrmse["soft"] < 0.05 and nrmse["hard"] < 0.06, nrmse
    assert res["objective"]["best"] < 0.8 * res["objective"]["start"]
