"""Test-only reader of the virtual laboratory's hidden truth (conf/lab/).

Calibration code never reads conf/lab; tests use this module to ask what a
fit should have found: the lab sample's true value of each fitted quantity
(design parameters and the benches' sensor bandwidths) and the objective
a fit reaches at that truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from conftest import ROOT
from dampertwin.design import load
from dampertwin.lab import _sensor_specs, load_sample, sample_design
from dampertwin.variants import load_variant

SENSOR_COLUMNS = {"sensor.force_bandwidth": "force [N]"}


def true_design(case: str | None, sample: str | Path = "sample.yaml"):
    """The real part behind a design case (None: the baseline) of a lab sample."""
    conf = ROOT / "conf"
    s = load_sample(conf / "lab" / sample)
    d = load(conf / "lab" / "nominal.yaml")
    if case:
        d = load_variant(conf / "variant" / f"{case}.yaml").apply(d)
    return sample_design(d, s), s


def true_values(keys, case: str | None, sample: str | Path = "sample.yaml") -> dict[str, float]:
    """The lab sample's true value of each fitted key (``sensor.*``: the
    bench's real transducer bandwidth)."""
    d, s = true_design(case, sample)
    return {k: float(_sensor_specs(s["benches"])[SENSOR_COLUMNS[k]]["corner"]) if k.startswith("sensor.")
            else float(d[k])
            for k in keys}


def objective_at_truth(records, specs, case: str | None, sample: str | Path = "sample.yaml") -> float:
    """A fit's eq. 6.x objective with every fitted quantity at the lab truth."""
    tv = true_values([s.key for s in specs], case, sample)
    return float(records.objective(np.array([[tv[s.key] for s in specs]]))[0])
