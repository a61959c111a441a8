"""DVC stage `approach2_sensitivity`: time-resolved grouped first-order
Sobol indices of the simulated damper force on the training signal (thesis
7.1 / 7.3, L1434-1436, L1527-1536; 4 valve groups, SALib grouped Saltelli,
profile n_base: 32 -> 320 runs), their bootstrap band, and the eq.-7.1
weights. Outputs results/approach2/sensitivity/: indices.parquet (S_i(t),
band, mask, weight), sensitivity.png (like thesis fig. 7.6a), metrics.json."""

import time

import matplotlib.pyplot as plt
import numpy as np

from _approach2 import OUT2, damper_record, profile_block
from _common import CONF, baseline, config_hash, seed_for, stage, staged_dir, write_json
from dampertwin.calibration import approach2, sensitivity as sens
from dampertwin.design import yaml_load_file
from dampertwin.io import runs, write_frame


def main() -> None:
    cfg, p2 = profile_block()
    cal = yaml_load_file(CONF / "calibration" / "approach2.yaml")
    rec, proto, mmeta = damper_record("training", p2.runs, p2.get("tail_s"))
    approach2.input_cutoff(cal, {"training": proto})  # a corner that would filter the motion: a clear error
    # the profile sets N and may choose the design (second_order); the rest is conf/calibration/approach2.yaml
    chosen = {k: p2.sensitivity[k] for k in ("second_order",) if k in p2.sensitivity}
    settings = approach2.SensitivitySettings.from_config({**cal["sensitivity"], **chosen},
                                                         n_base=int(p2.sensitivity.n_base))
    wset = sens.WeightSettings.from_config(cal["weights"])
    seed = seed_for("approach2_sensitivity")
    t0 = time.perf_counter()
    prob, res, Y = approach2.sensitivity(baseline(), rec, cal, settings, seed,
                                         bandwidth=proto.get("sensors", {}).get("force"),
                                         max_wall_s=float(p2.ga.max_wall_s), scheduler=cfg.profile.scheduler)
    wall = time.perf_counter() - t0
    print(f"approach2_sensitivity: {res.meta['runs']} runs in {wall:.1f} s wall", flush=True)  # not an artifact: same config, same bytes
    W = sens.weights(res.S1, prob.time, wset)
    df = res.to_frame(prob.time)
    G = len(res.groups)
    labels = np.array([n for n, _ in runs(rec)], dtype=object)  # the order of the problem's cases
    df["run"] = np.tile(labels[prob.run], G)
    df["weight [-]"] = W.ravel()
    meta = {"stage": "approach2_sensitivity", "profile": cfg.profile.name, "seed": seed, "config_hash": config_hash(),
            "measured_seed": mmeta.get("seed"), "synthetic": bool(mmeta.get("synthetic")), **res.meta,
            "weights": {"clip": list(wset.clip), "smooth_s": wset.smooth_s, "normalise": wset.normalise},
            "time": "training runs laid end to end [s]"}
    with staged_dir(OUT2 / "sensitivity") as tmp:
        write_frame(tmp / "indices.parquet", df, meta)
        fig = sens.figure(prob.time, res, prob.measured, "measured force [N]",
                          f"First-order Sobol index of the simulated force, {res.meta['runs']} runs "
                          f"(thesis fig. 7.6a; profile {cfg.profile.name})")
        fig.savefig(tmp / "sensitivity.png", dpi=100)
        plt.close(fig)
        live = ~res.masked
        write_json(tmp / "metrics.json", {
            "runs": res.meta["runs"], "n_base": settings.n_base, "failed_runs": res.meta["failed_runs"],
            "dropped_base_samples": res.meta["dropped_base_samples"],
            "masked_instants": int(res.masked.sum()), "instants": int(len(res.masked)),
            "mean_S1": {g: float(np.mean(res.S1[i, live])) for i, g in enumerate(res.groups)},
            "mean_conf": {g: float(np.mean(res.S1_conf[i, live])) for i, g in enumerate(res.groups)},
            "sum_mean_S1": float(np.sum(np.mean(res.S1[:, live], axis=1)))})


if __name__ == "__main__":
    stage(main, "approach2_sensitivity")
