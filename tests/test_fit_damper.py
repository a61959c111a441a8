"""``dampertwin fit damper``: the valves' and the gas's parameters fitted on dyno records of one clicker setting,
the other settings predicted. The records here are model-generated (synthetic, labelled so in their metadata,
written from the model with parameters moved away from the design's): a recovery check of the fitting path,
not a check against other physics."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dampertwin import cli
from dampertwin.calibration.damper_fit import default_items, present_valves
from dampertwin.design import load
from dampertwin.excitation import Excitation
from dampertwin.io import write_frame
from dampertwin.simulation import simulate

ROOT = Path(__file__).resolve().parents[1]
TWIN = ROOT / "conf" / "design" / "twin_tube.yaml"
# the "real" damper behind the records: preloads and gas content off the design's values
TRUE = {"piston_rebound.F_preload": 260.0, "base_compression.F_preload": 380.0, "oil.chi": 0.008}
SPEEDS = (0.1, 0.3, 0.6)  # peak velocities [m/s] of the sine steps
AMPLITUDE = 0.015  # [m]
RATE = 1000.0  # [Hz]


def _dyno_record(design, setting: dict, path: Path, seed: int) -> Path:
    """A synthetic dyno record: one run per speed, 2 cycles each, force with 5 N noise."""
    d = design.at_setting(setting).with_overrides(TRUE)
    rng = np.random.default_rng(seed)
    frames = []
    for v in SPEEDS:
        f = v / (2 * np.pi * AMPLITUDE)
        r = simulate(d, Excitation.sine(AMPLITUDE, f, 2.0 / f), "damper", current=0.0, rate=RATE)
        frames.append(pd.DataFrame({"time [s]": r.time - r.time[0], "displacement [m]": r["displacement [m]"],
                                    "force [N]": r["rod force [N]"] + rng.normal(0.0, 5.0, len(r.time)),
                                    "run": f"v{v:g}"}))
    meta = {"synthetic": True, "source": "model-generated dyno record (tests/test_fit_damper.py)",
            "setting": setting}
    return write_frame(path, pd.concat(frames, ignore_index=True), meta)


def test_default_search_space_follows_the_architecture():
    twin, mono = load(TWIN), load(ROOT / "conf" / "design" / "mono_tube.yaml")
    assert present_valves(twin) == ("piston_rebound", "piston_intake", "base_compression", "base_intake")
    assert present_valves(mono) == ("piston_rebound", "piston_intake")
    keys = [i["key"] for i in default_items(twin)]
    assert "oil.chi" in keys and "base_compression.F_preload" in keys
    assert "piston_rebound.A_bleed" not in keys  # moved by the rebound clicker: a record's setting, not fitted
    assert not any(k.startswith("base_") for k in (i["key"] for i in default_items(mono)))


def test_fit_damper_on_one_setting_predicts_the_others(tmp_path):
    design = load(TWIN)
    fitted = _dyno_record(design, {"rebound": 3, "compression": 2}, tmp_path / "click3.parquet", 1)
    soft = _dyno_record(design, {"rebound": 6, "compression": 4}, tmp_path / "click6.parquet", 2)
    hard = _dyno_record(design, {"rebound": 0, "compression": 0}, tmp_path / "click0.parquet", 3)
    from dampertwin.io import read_table

    df, meta = read_table(soft)  # negative control: the soft record without its setting (taken at the design's)
    unlabelled = write_frame(tmp_path / "click6_unlabelled.parquet", df, {k: v for k, v in meta.items()
                                                                          if k != "setting"})
    out = tmp_path / "fit"
    rc = cli.main(["fit", "damper", "--design", str(TWIN), "--data", str(fitted), "--predict", str(soft), str(hard),
                   str(unlabelled),
                   "--out", str(out), "--population", "12", "--generations", "8",
                   "--param", "piston_rebound.F_preload=100:400", "--param", "base_compression.F_preload=150:600",
                   "--param", "oil.chi=0.001:0.03:log"])
    assert rc == 0
    res = json.loads((out / "fit.json").read_text())
    files = res["files"]
    assert files[str(fitted)]["role"] == "fitted" and files[str(soft)]["role"] == "predicted"
    assert files[str(soft)]["setting"] == {"rebound": 6, "compression": 4}
    # the design's own values (before the fit) miss the records by far more than the fitted ones
    start = res["objective"]["start"]
    assert res["objective"]["best"] < 0.5 * start
    for f in (fitted, soft, hard):
        assert files[str(f)]["nrmse"] < 0.03, (f, files[str(f)])
    assert files[str(unlabelled)]["nrmse"] > 3 * files[str(soft)]["nrmse"]  # the setting is what predicts it
    assert res["parameters"]["piston_rebound.F_preload"] == pytest.approx(TRUE["piston_rebound.F_preload"], rel=0.15)
    assert any(p.suffix == ".png" for p in out.iterdir())


def test_a_record_naming_a_setting_the_design_lacks_is_refused(tmp_path):
    design = load(TWIN)
    bad = _dyno_record(design, {"rebound": 3, "compression": 2}, tmp_path / "r.parquet", 1)
    from dampertwin.io import read_table

    df, meta = read_table(bad)
    meta["setting"] = {"rebound": 9}
    write_frame(bad, df, meta)
    with pytest.raises(Exception, match=r"rebound"):
        from dampertwin.cli_fit_files import fit_damper

        fit_damper([bad], design=TWIN, population=4, generations=1)


def test_bleeds_are_fitted_unless_a_clicker_moves_them_and_a_record_without_setting_is_flagged(tmp_path):
    from dampertwin.design.adjusters import without_adjusters

    free = without_adjusters(load(TWIN))
    keys = [i["key"] for i in default_items(free)]
    assert "piston_rebound.A_bleed" in keys and "base_compression.A_bleed" in keys
    assert "piston_intake.A_bleed" not in keys  # an intake disc has no bleed
    assert "sensor.force_offset" in keys  # the dyno's tared zero
    rec = _dyno_record(load(TWIN), {"rebound": 3, "compression": 2}, tmp_path / "r.parquet", 1)
    from dampertwin.io import read_table

    df, meta = read_table(rec)
    write_frame(rec, df, {k: v for k, v in meta.items() if k != "setting"})
    from dampertwin.cli_fit_files import fit_damper

    res = fit_damper([rec], design=TWIN, population=4, generations=1)
    assert any("names no clicker setting" in f for f in res["flags"])
