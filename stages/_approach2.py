"""Shared helpers of the approach-2 stage scripts (thesis chapter 7, issue
12): output folder, profile block, the measured training record and the two
calibrated designs compared side by side. Approach 2's design reads no
approach-1 result (its top mount: stage approach2_topmount)."""

from __future__ import annotations

from _common import CONF, ROOT, OUT, study_design, config, measured_dir, read_overlay
from dampertwin.calibration.approach2 import check_damper_record
from dampertwin.design import load
from dampertwin.errors import UserError
from dampertwin.io import read_record
from dampertwin.protocols import load_protocol

OUT2 = ROOT / "results" / "approach2"
CURRENTS = {"I1.6": "baseline_1.6", "I0.9": "baseline_0.9", "I0.32": "baseline_0.32"}  # run -> approach-1 case


def profile_block():
    cfg = config()
    if "approach2" not in cfg.profile:
        raise UserError(f"conf/profile/{cfg.profile.name}.yaml: missing the approach2 block "
                        "(runs, sensitivity.n_base, ga)")
    return cfg, cfg.profile.approach2


def damper_record(test: str, runs=None, tail_s=None):
    """A damper-level record (training | verification) of the measurement
    folder, checked, restricted to ``runs`` (and the last ``tail_s`` seconds
    of each); with its protocol."""
    path = measured_dir() / test / "baseline.parquet"
    proto = load_protocol(CONF / "test" / f"{test}.yaml")
    df, meta = read_record(path)
    return check_damper_record(df, str(path), list(runs) if runs else None, tail_s), proto, meta


def approach2_design():
    """baseline + approach-2 valves / compliance + approach 2's top mount,
    fitted on the module-level test (thesis 7.2; stage approach2_topmount).
    Nothing of approach 1."""
    d = study_design().with_overrides(read_overlay(OUT2 / "fit" / "overlay.yaml"))
    return d.with_overrides(read_overlay(OUT2 / "topmount" / "overlay.yaml"))


def approach1_design():
    """The approach-1 design, only to be simulated beside approach 2's (the comparison)."""
    return load(OUT / "designs" / "baseline_1.6.yaml")  # its P/Q map beside it (stage assemble)
