"""Dyno records in the discrepancy workflow: a speed program is cut into its steps (sine units), a warm-up run
keeps its temperature history, and a warm-up of a passive damper is named oil heating or left unexplained,
never a valve effect. Records are model-generated (synthetic, labelled so): a check of the path, not of the
workflow against other physics."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.signal import lfilter

from dampertwin import cli
from dampertwin.design import load
from dampertwin.discrepancy.features import TEMP, dyno_segments
from dampertwin.excitation import Excitation
from dampertwin.io import write_frame
from dampertwin.protocols import build_runs, load_protocol
from dampertwin.simulation import simulate

ROOT = Path(__file__).resolve().parents[1]
TWIN = ROOT / "conf" / "design" / "twin_tube.yaml"
FS = 300.0  # [Hz] a dyno export's rate


def _record(r, seed: int) -> pd.DataFrame:
    """Force with 3 N noise, the oil temperature through a 0.16 Hz thermocouple lag (conf/test/dyno.yaml)."""
    T = r["oil temperature [K]"]
    a = np.exp(-2 * np.pi * 0.16 / FS)
    rng = np.random.default_rng(seed)
    return pd.DataFrame({"time [s]": r.time - r.time[0], "displacement [m]": r["displacement [m]"],
                         "force [N]": r["rod force [N]"] + rng.normal(0, 3.0, len(T)),
                         TEMP: lfilter([1 - a], [1, -a], T - T[0]) + T[0] + rng.normal(0, 0.02, len(T)),
                         "run": "passive"})


@pytest.fixture(scope="module")
def warm_damper():
    return load(TWIN).with_overrides({"effects.oil_thermal": True})


def _program(d):
    run = build_runs(load_protocol(ROOT / "conf" / "test" / "dyno.yaml"))[0]
    return _record(simulate(d, run.excitation, "damper", current=0.0, rate=FS), 1)


def _warmup(d, seconds=20.0):
    A, v = 0.025, 0.4
    return _record(simulate(d, Excitation.sine(A, v / (2 * np.pi * A), seconds), "damper", current=0.0, rate=FS), 0)


def test_a_speed_program_is_cut_into_its_steps_and_a_warm_up_stays_whole(warm_damper):
    prog = _program(warm_damper)
    segs = dyno_segments("passive", prog)
    speeds = [float(n.split("@")[1].removesuffix("m/s")) for n, _ in segs]
    assert speeds == pytest.approx([0.05, 0.1, 0.2, 0.3, 0.5], rel=0.03)  # conf/test/dyno.yaml
    assert all(TEMP not in g for _, g in segs)  # a cut step's temperature history is not simulated
    warm = _warmup(warm_damper, 8.0)
    (name, whole), = dyno_segments("passive", warm)  # the stroke's fade-in is no step of its own
    assert name == "passive" and len(whole) == len(warm) and TEMP in whole


@pytest.mark.slow
def test_a_warm_up_run_is_oil_heating_or_unexplained_never_a_valve(warm_damper, tmp_path):
    meas = tmp_path / "measured" / "dyno"
    for name, df in (("program", _program(warm_damper)), ("warmup", _warmup(warm_damper))):
        write_frame(meas / f"{name}.parquet", df, {"synthetic": True, "protocol": "dyno",
                                                   "source": "model-generated, oil_thermal on"})
    out = tmp_path / "out"
    assert cli.main(["discrepancy", "--design", str(TWIN), "--measured", str(meas.parent), "--out", str(out),
                     "--profile", "ci", "--workers", "1"]) == 0
    v = json.loads((out / "verdict.json").read_text())
    assert v["verdict"] in ("named", "unexplained"), v["verdict"]
    valve = ("valve", "piston_leakage", "aeration")
    assert not any(k in e for e in v["effects"] for k in valve), v["effects"]
    if v["verdict"] == "named":
        assert "oil_thermal" in v["effects"]
    report = (out / "report.md").read_text()
    assert "| dyno | warmup | temperature rise" in report  # where it disagrees: the thermocouple
