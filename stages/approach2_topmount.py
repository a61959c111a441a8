"""DVC stage `approach2_topmount`: approach 2's top mount, fitted on the
module-level test (thesis 7.2, figs. 7.2 / 7.4): the rod's LVDT against the
top-mount housing as the input, the load cell as the output, the training
signal at the lower mount. Static curve a 5th-order polynomial by least
squares, then the AutoBushFD parameters by GA with approach 1's settings
and the table 6.4 limits (conf/calibration/topmount.yaml, the profile's
ga.topmount; eq. 6.3). -> results/approach2/topmount/ (overlay.yaml,
metrics.json, history.parquet, uncertainty.*, topmount.png)."""

import matplotlib.pyplot as plt
import numpy as np

from _approach2 import OUT2
from _common import CONF, study_design, valve_map, config, measured_dir, seed_for, stage, staged_dir, write_fit
from dampertwin.calibration.ga import GASettings
from dampertwin.calibration.identifiability import sweep_points, top_mount_report
from dampertwin.calibration.module_topmount import calibration, fit_module_top_mount
from dampertwin.checkpoint import NpzStore
from dampertwin.calibration.polish import PolishSettings
from dampertwin.design import yaml_load_file
from dampertwin.io import read_record
from dampertwin.protocols import load_protocol
from dampertwin.report import simulate_from_record

TEST = "module_topmount"
PLOT_S = 2.0  # [s] of the record shown: the 10 mm-stroke bursts (the fastest rubber deflections)


def figure(path, d, fitted, rec, coef, kept: str, cutoff: float, name: str) -> None:
    """Fig. 7.4 a/b: measured and simulated force over the last PLOT_S of the
    run; the force-deflection characteristic: measured, the fitted model's
    total force (static curve + rubber dynamics) and the static curves alone
    (nominal, fitted: which one was kept is ``kept``)."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
    t = rec["time [s]"].to_numpy()
    m = t >= t[-1] - PLOT_S
    axes[0].plot(t[m], rec["force [N]"].to_numpy()[m], lw=0.8, label="measured (load cell)")
    sims = {}
    for label, dd, st in (("nominal", d, ":"), ("fitted", fitted, "--")):
        r = simulate_from_record(dd, rec, "topmount", 0.0, cutoff=cutoff)
        sims[label] = np.asarray(r["top mount force [N]"])
        axes[0].plot(r.time[m[: len(r.time)]], sims[label][m[: len(r.time)]], st, label=label)
    X = rec["displacement [m]"].to_numpy()
    step = max(1, len(X) // 5000)
    axes[1].plot(1e3 * X[::step], rec["force [N]"].to_numpy()[::step], ".", ms=1.5, alpha=0.4, label="measured")
    n = min(len(X), len(sims["fitted"]))
    axes[1].plot(1e3 * X[:n][m[:n]], sims["fitted"][:n][m[:n]], "-", lw=0.6, color="tab:green", alpha=0.7,
                 label=f"fitted model, last {PLOT_S:g} s (static curve + rubber dynamics)")
    xs = np.linspace(X.min(), X.max(), 200)
    for label, c, st in (("nominal F_LD (static part)", d["top_mount.F_LD"], ":"),
                         (f"F_LD kept: {kept} (static part alone)", coef, "-.")):
        axes[1].plot(1e3 * xs, sum(ck * xs ** (k + 1) for k, ck in enumerate(c)), st, color="black" if st == "-." else None,
                     label=label)
    axes[0].set(xlabel="time [s]", ylabel="force [N]", title=f"module test {name}: load cell, last {PLOT_S:g} s (fig. 7.4a)")
    axes[1].set(xlabel="rod against housing (LVDT) [mm]", ylabel="force [N]",
                title="force-deflection; static curve F_LD (thesis fig. 7.4b)")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.savefig(path, dpi=100, metadata={"Software": None})
    plt.close(fig)


def main() -> None:
    cfg = config()
    d = study_design()
    where = "conf/calibration/approach2_topmount.yaml"
    cal = calibration(yaml_load_file(CONF / "calibration" / "approach2_topmount.yaml"),
                      yaml_load_file(CONF / "calibration" / "topmount.yaml").get("parameters"), where)
    proto = load_protocol(CONF / "test" / f"{TEST}.yaml")
    meas, _ = read_record(measured_dir() / TEST / "baseline.parquet", TEST, conf=CONF)
    seed = seed_for("approach2_topmount")
    ck = NpzStore(OUT2 / "checkpoints" / "approach2_topmount.npz")  # kept only while the fit runs
    res, coef, kept, rec = fit_module_top_mount(
        d, meas, cal, GASettings.from_config(cfg.profile.ga.topmount), seed, checkpoint=ck,
        scheduler=cfg.profile.scheduler, polish_settings=PolishSettings.from_config(cfg.profile.polish),
        force_bandwidth=proto.get("sensors", {}).get("force"))
    best = {**res.best, "top_mount.F_LD": coef}  # sensor.* (nuisance) values are kept out of the overlay
    meta = {"fit": "approach2_topmount", "test": TEST, "run": cal["dynamic_run"], "profile": cfg.profile.name,
            "seed": seed, "valve_map": valve_map(), "objective": "eq. 6.3 int|F_test - F_sim| dt [N*s]",
            "static_curve": kept,
            "input": "the LVDT's rod displacement against the top-mount housing (thesis 7.2)"}
    # what the record determines: |K*| and loss angle at the component sweep's frequencies (thesis fig. 7.5)
    determined = top_mount_report(d.with_overrides({"top_mount.F_LD": coef}), res.best, res.uncertainty, res.specs,
                                  *sweep_points(load_protocol(CONF / "test" / "topmount.yaml")))
    out = OUT2 / "topmount"
    with staged_dir(out) as tmp:  # all outputs or none
        write_fit(tmp, res, meta, "N*s", d.hash(), best=best,
                  extra={"determined": determined, "valve_map": meta["valve_map"]})
        fitted = d.with_overrides({k: v for k, v in best.items() if not k.startswith("sensor.")})
        figure(tmp / "topmount.png", d, fitted, rec, coef, kept, cal["input_cutoff"], cal["dynamic_run"])
    ck.path.unlink(missing_ok=True)  # the fit is complete: its checkpoint is spent


if __name__ == "__main__":
    stage(main, "approach2_topmount")
