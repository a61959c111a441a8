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

SENSOR_COLUMNS = {"sensor.force_bandwidth": "force [N]", "sensor.force_delay": "force [N]"}
DELAY_AT = 20.0  # Hz: the low-frequency group delay that a pure-delay nuisance stands for


def _group_delay(spec: dict, fs: float) -> float:
    """Group delay [s] at DELAY_AT of a transducer description (sensors.transducer)."""
    from scipy import signal

    if spec.get("filter", "none") == "none" or spec.get("corner") is None or spec["corner"] >= 0.45 * fs:
        return 0.0
    if spec["filter"] == "butter":
        ba = signal.butter(spec.get("order", 2), spec["corner"], fs=fs)
    else:
        ba = signal.bessel(spec.get("order", 2), spec["corner"], norm="mag", fs=fs)
    return float(signal.group_delay(ba, w=[DELAY_AT], fs=fs)[1][0]) / fs


def true_force_delay(sample: str | Path, protocol: str = "topmount") -> float:
    """The lab's force chain's delay beyond the documented 2nd-order
    Butterworth's (conf/test/<protocol>.yaml) [s]: what sensor.force_delay should find."""
    from dampertwin.protocols import load_protocol

    proto = load_protocol(ROOT / "conf" / "test" / f"{protocol}.yaml")
    fs = float(proto["rate"])
    real = _sensor_specs(load_sample(ROOT / "conf" / "lab" / "lab2" / sample)["benches"])["force [N]"]
    documented = {"filter": "butter", "order": 2, "corner": proto["sensors"]["force"]}
    return _group_delay(real, fs) - _group_delay(documented, fs)


def true_design(case: str | None, sample: str | Path = "sample.yaml"):
    """The real part behind a design case (None: the baseline) of a lab sample."""
    conf = ROOT / "conf"
    s = load_sample(conf / "lab" / "lab2" / sample)
    d = load(conf / "lab" / "nominal.yaml")
    if case:
        d = load_variant(conf / "variant" / f"{case}.yaml").apply(d)
    return sample_design(d, s), s


def true_values(keys, case: str | None, sample: str | Path = "sample.yaml", protocol: str = "topmount") -> dict[str, float]:
    """The lab sample's true value of each fitted key (``sensor.*``: the
    bench's real transducer bandwidth)."""
    d, s = true_design(case, sample)
    if OFFSET in keys:
        raise KeyError(f"{OFFSET}: no single true value; objective_at_truth finds the truth's best")
    def sensor(k):
        if k == "sensor.force_delay":
            return true_force_delay(sample, protocol)
        return float(_sensor_specs(s["benches"])[SENSOR_COLUMNS[k]]["corner"])

    return {k: sensor(k) if k.startswith("sensor.") else float(d[k]) for k in keys}


def objective_at_truth(records, specs, case: str | None, sample: str | Path = "sample.yaml",
                       protocol: str = "topmount") -> float:
    """A fit's eq. 6.x objective with every fitted quantity at the lab truth.
    A fitted load-cell zero (``sensor.force_offset``) has no single true
    value (the static curve's fitted zero absorbs part of the bench's
    offsets): it takes the one that is best for the truth, the weighted
    median of the truth's residual (the minimiser of sum w |e - c|)."""
    keys = [s.key for s in specs]
    row = np.array([[true_values([k], case, sample, protocol)[k] if k != OFFSET else 0.0 for k in keys]])
    if OFFSET in keys:
        e = records.residuals(row)[0]
        order = np.argsort(e)
        cw = np.cumsum(records.weights[order])
        row[0, keys.index(OFFSET)] = e[order][np.searchsorted(cw, 0.5 * cw[-1])]
    return float(records.objective(row)[0])


OFFSET = "sensor.force_offset"


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
