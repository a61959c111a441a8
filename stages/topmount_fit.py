"""DVC stage `topmount_fit@<baseline|alternative>`: static curve by least
squares and GA fit of the AutoBushFD parameters on the random record
(thesis 6.4, eq. 6.3, table 6.4)."""

import matplotlib.pyplot as plt
import pandas as pd

from _common import (CONF, OUT, baseline, checkpoint, checkpoint_store, choice, config, design_values, measured_dir,
                     seed_for, stage, staged_dir, write_fit)
from dampertwin import kpi
from dampertwin.calibration.approach1 import fit_top_mount
from dampertwin.calibration.ga import GASettings
from dampertwin.calibration.identifiability import sweep_points, top_mount_report
from dampertwin.design import yaml_load_file
from dampertwin.calibration.polish import PolishSettings
from dampertwin.io import read_record, runs
from dampertwin.protocols import load_protocol
from dampertwin.report import simulate_from_record
from dampertwin.variants import TOP_MOUNTS, load_variant


def main(name: str) -> None:
    cfg = config()
    d = baseline()
    if TOP_MOUNTS[choice(name, TOP_MOUNTS, "top mount")]:
        d = load_variant(CONF / "variant" / f"{TOP_MOUNTS[name]}.yaml").apply(d)
    cal = yaml_load_file(CONF / "calibration" / "topmount.yaml")
    proto = load_protocol(CONF / "test" / "topmount.yaml")
    meas, _ = read_record(measured_dir() / "topmount" / f"{name}.parquet", "topmount", conf=CONF)
    seed = seed_for(f"topmount_fit/{name}")
    out = OUT / "topmount" / name
    bandwidth = proto.get("sensors", {}).get("force")
    res, coef, kept = fit_top_mount(d, meas, cal, GASettings.from_config(cfg.profile.ga.topmount), seed,
                              checkpoint=checkpoint_store(f"topmount_{name}"), scheduler=cfg.profile.scheduler,
                              polish_settings=PolishSettings.from_config(cfg.profile.polish),
                              force_bandwidth=bandwidth)
    best = {**res.best, "top_mount.F_LD": coef}  # sensor.* (nuisance) values are kept out of the overlay
    meta = {"fit": "topmount_fit", "top_mount": name, "profile": cfg.profile.name, "seed": seed,
            "objective": "eq. 6.3 int|F_test - F_sim| dt [N*s]", "static_curve": kept}
    # what the record determines: dynamic stiffness and loss angle at the sweep's frequencies, with bands
    determined = top_mount_report(d.with_overrides({"top_mount.F_LD": coef}), res.best, res.uncertainty, res.specs,
                                  *sweep_points(proto))
    with staged_dir(out) as tmp:  # all outputs or none
        write_fit(tmp, res, meta, "N*s", d.hash(), best=best, extra={"determined": determined})
        fitted = d.with_overrides(design_values(best))
        fig, axes = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
        g = dict(runs(meas))["random"]
        m = g["time [s]"] <= g["time [s]"].iloc[0] + 2.0
        axes[0].plot(g["time [s]"][m], g["force [N]"][m], lw=0.8, label="measured")
        for label, dd, st in (("nominal", d, ":"), ("fitted", fitted, "--")):
            r = simulate_from_record(dd, g, "topmount", 0.0)
            mm = r.time <= r.time[0] + 2.0
            axes[0].plot(r.time[mm], r["top mount force [N]"][mm], st, label=label)
            sw = []
            for rn, gg in runs(meas):
                if rn.startswith("sweep_A0.0001"):
                    rr = simulate_from_record(dd, gg, "topmount", 0.0)
                    sw.append(kpi.dynamic_stiffness(rr.to_frame().assign(run=rn).rename(
                        columns={"top mount force [N]": "force [N]"})))
            ds = pd.concat(sw)
            axes[1].semilogx(ds["frequency [Hz]"], ds["stiffness [N/m]"] / 1e3, st + "o", label=label)
        dm = kpi.dynamic_stiffness(meas)
        dm = dm[dm.run.str.startswith("sweep_A0.0001")]
        axes[1].semilogx(dm["frequency [Hz]"], dm["stiffness [N/m]"] / 1e3, "-s", label="measured")
        axes[0].set(xlabel="time [s]", ylabel="force [N]", title=f"top mount {name}: random record (first 2 s)")
        axes[1].set(xlabel="frequency [Hz]", ylabel="dynamic stiffness [N/mm]", title="0.1 mm sweep")
        for ax in axes:
            ax.grid(alpha=0.3)
            ax.legend()
        fig.savefig(tmp / "topmount.png", dpi=100)
        plt.close(fig)
    checkpoint(f"topmount_{name}").unlink(missing_ok=True)  # the fit is complete: its checkpoint is spent


if __name__ == "__main__":
    stage(main, "topmount_fit")
