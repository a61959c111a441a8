"""`dampertwin fit valve` and the study's flow-bench stage (stages/flowbench_fit.py)
give the same fit on the same lab record and seed: both go through
calibration.approach1.fit_valve with the same search space, bench, budgets,
input low-pass and polish (issue 33, item 4)."""

from __future__ import annotations

import json

import pytest
import yaml

from conftest import BASELINE, ROOT
from dampertwin.cli import main

VALVE = "piston_intake"
SEED = 11
# a small budget (smaller than the ci profile's) so the two fits take seconds; the same for both routes
BUDGET = {"ga": {"valves": {"population": 4, "reproduction_ratio": 80, "generations": 2, "mutation_probability": 10,
                            "max_wall_s": 300}},
          "polish": {"starts": 1, "max_nfev": 4}, "scheduler": None}


@pytest.fixture(scope="module")
def lab_record(tmp_path_factory):
    """The lab's flow-bench record of the valve: data/measured's when the
    study's lab stage has run here, else the lab run for this one case."""
    path = ROOT / "data" / "measured" / "flowbench" / f"{VALVE}.parquet"
    if path.is_file():
        return path
    from dampertwin.lab import generate

    out = tmp_path_factory.mktemp("lab")
    seed = int(yaml.safe_load((ROOT / "conf" / "config.yaml").read_text())["seed"])
    generate(ROOT / "conf", out, seed, only=[("flowbench", VALVE)], progress=False, workers=1)
    return out / "flowbench" / f"{VALVE}.parquet"


def test_fit_valve_and_the_flowbench_stage_give_the_same_fit(lab_record, tmp_path, monkeypatch):
    from dampertwin.calibration.uncertainty import summary
    from dampertwin.design import load

    monkeypatch.syspath_prepend(str(ROOT / "stages"))
    import flowbench_fit

    res, _, _, _ = flowbench_fit.fit_record(load(BASELINE), VALVE, lab_record, BUDGET, SEED)
    assert res.polish and res.best_objective < res.objective_ga  # the polish moved the GA's result

    cfg = tmp_path / "budget.yaml"
    cfg.write_text(yaml.safe_dump({"ga": BUDGET["ga"]["valves"], "polish": BUDGET["polish"]}))
    out = tmp_path / "fit"
    assert main(["fit", "valve", "--valve", VALVE, "--data", str(lab_record), "--out", str(out), "--design",
                 str(BASELINE), "--bounds", str(cfg), "--seed", str(SEED)]) == 0
    # standard JSON (RFC 8259): an unbounded interval is null, never an Infinity token
    doc = json.loads((out / "fit.json").read_text(), parse_constant=lambda c: pytest.fail(f"fit.json holds {c}"))

    assert doc["parameters"] == res.best
    assert doc["objective"]["best"] == res.best_objective and doc["objective"]["start"] == res.start_objective
    assert doc["polish"]["objective_polished"] == res.polish["objective_polished"]
    assert doc["bounds"] == {s.key: [s.lo, s.hi, s.scale] for s in res.specs}
    assert doc["bound_hits"] == res.bound_hits
    from dampertwin.io import json_safe
    assert doc["uncertainty"] == json_safe(summary(res.uncertainty))
    assert doc["uncertainty"]["parameters"]["piston_intake.a"]["ci95"] == [None, None]  # unbounded here
