"""DVC stage `compliance_fit`: GA fit of gas content and oil bulk modulus
on the damper-level 10 mm sine test (thesis 6.3, eq. 6.2), with the four
baseline valve fits applied."""

import matplotlib.pyplot as plt

from _common import (CONF, OUT, study_design, valve_map, checkpoint, checkpoint_store, config, design_values,
                     measured_dir, read_overlay, seed_for, stage, staged_dir, write_fit)
from dampertwin.calibration.approach1 import fit_compliance
from dampertwin.calibration.ga import GASettings
from dampertwin.design import yaml_load_file
from dampertwin.calibration.polish import PolishSettings
from dampertwin.io import read_record, runs
from dampertwin.protocols import load_protocol
from dampertwin.report import simulate_from_record

VALVES = ("piston_rebound", "piston_intake", "base_compression", "base_intake")


def main() -> None:
    cfg = config()
    d = study_design()
    for v in VALVES:
        d = d.with_overrides(read_overlay(OUT / "valves" / v / "overlay.yaml"))
    cal = yaml_load_file(CONF / "calibration" / "compliance.yaml")
    proto = load_protocol(CONF / "test" / "compliance.yaml")
    meas, _ = read_record(measured_dir() / "compliance" / "baseline.parquet", "compliance", conf=CONF)
    seed = seed_for("compliance_fit")
    out = OUT / "compliance"
    bandwidth = proto.get("sensors", {}).get("force")
    res = fit_compliance(d, meas, cal, GASettings.from_config(cfg.profile.ga.compliance), seed,
                         checkpoint=checkpoint_store("compliance"), scheduler=cfg.profile.scheduler,
                         polish_settings=PolishSettings.from_config(cfg.profile.polish),
                         force_bandwidth=bandwidth)
    meta = {"fit": "compliance_fit", "profile": cfg.profile.name, "seed": seed, "valve_map": valve_map(),
            "objective": "eq. 6.2 int|F_test - F_sim| dt [N*s]"}
    with staged_dir(out) as tmp:  # all outputs or none
        write_fit(tmp, res, meta, "N*s", d.hash(), extra={**res.best, "valve_map": meta["valve_map"]})
        fitted = d.with_overrides(design_values(res.best))
        fig, axes = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
        name, g = runs(meas)[-1]
        for label, dd, st in (("nominal", d, ":"), ("fitted", fitted, "--")):
            r = simulate_from_record(dd, g, "damper", float(g["current [A]"].iloc[0]))
            axes[0].plot(r.time, r["rod force [N]"], st, label=label)
            axes[1].plot(r["velocity [m/s]"], r["rod force [N]"], st, label=label)
        axes[0].plot(g["time [s]"], g["force [N]"], lw=0.8, alpha=0.7, label="measured")
        v = g["displacement [m]"].diff() / g["time [s]"].diff()
        axes[1].plot(v.rolling(25, center=True).mean(), g["force [N]"], lw=0.8, alpha=0.7, label="measured")
        axes[0].set(xlabel="time [s]", ylabel="force [N]", title=f"compliance test, run {name}")
        axes[1].set(xlabel="velocity [m/s]", ylabel="force [N]", title="force-velocity hysteresis")
        for ax in axes:
            ax.grid(alpha=0.3)
            ax.legend()
        fig.savefig(tmp / "compliance.png", dpi=100)
        plt.close(fig)
    checkpoint("compliance").unlink(missing_ok=True)  # the fit is complete: its checkpoint is spent


if __name__ == "__main__":
    stage(main, "compliance_fit")
