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


def stiffness(x, pre, a, b, c, d):
    """Shim / intake valve spring force [N] at lift x [m] (thesis eq. 4.24)."""
    return pre + a * (np.exp(b * x) - 1) + c * (np.exp(d * x) - 1)


def stiffness_curve_error(fitted, real, valve: str) -> float:
    """Largest |F_fitted - F_real| / F_real of a valve's stiffness curve over
    the lift range the real valve reaches on the flow bench (protocol
    conf/test/flowbench.yaml); ``fitted`` and ``real`` are designs."""
    from dampertwin.protocols import build_runs, load_protocol
    from dampertwin.simulation import simulate

    fb = load_protocol(ROOT / "conf" / "test" / "flowbench.yaml")
    bench = {"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]}
    run = next(r for r in build_runs(fb) if r.bench_valve == valve)
    lift = simulate(real, run.excitation, "valve", bench_valve=valve, rate=run.rate, bench=bench)["lift [m]"]
    x = np.linspace(0.0, float(np.nanmax(lift)), 200)
    g_r, g_f = real.group(valve), fitted.group(valve)
    F_r = stiffness(x, g_r["F_preload"], g_r["a"], g_r["b"], g_r["c"], g_r["d"])
    F_f = stiffness(x, g_f["F_preload"], g_f["a"], g_f["b"], g_f["c"], g_f["d"])
    return float(np.max(np.abs(F_f - F_r) / F_r))
