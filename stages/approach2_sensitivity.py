"""DVC stage `approach2_sensitivity`: time-resolved grouped first-order
Sobol indices of the simulated damper force on the training signal (thesis
7.1 / 7.3, L1434-1436, L1527-1536; 4 valve groups, SALib grouped Saltelli,
profile n_base, doubled up to n_max until the weight curves converge),
their bootstrap band, and the eq.-7.1 weights (lower confidence bound).
Outputs results/approach2/sensitivity/: indices.parquet (S_i(t), band,
mask, weight), sensitivity.png (thesis fig. 7.6 a-d: indices, band,
weights and each valve's opening in the nominal simulation), metrics.json
(with the N sequence, the change per doubling, converged)."""

import time

import matplotlib.pyplot as plt
import numpy as np

from _approach2 import OUT2, damper_record, profile_block
from _common import CONF, study_design, valve_map, config_hash, seed_for, stage, staged_dir, write_json
from dampertwin.calibration import approach2, sensitivity as sens
from dampertwin.design import yaml_load_file
from dampertwin.errors import UserError
from dampertwin.io import runs, write_frame

FOCUS_S = 0.3  # s, width of the figure's focus window around the highest measured force (thesis fig. 7.6b, d)


def main() -> None:
    cfg, p2 = profile_block()
    cal = yaml_load_file(CONF / "calibration" / "approach2.yaml")
    rec, proto, mmeta = damper_record("training", p2.runs, p2.get("tail_s"))
    approach2.input_cutoff(cal, {"training": proto})  # a corner that would filter the motion: a clear error
    # the profile sets N and may choose the design (second_order); the rest is conf/calibration/approach2.yaml
    chosen = {k: p2.sensitivity[k] for k in ("second_order", "n_max") if k in p2.sensitivity}
    settings = approach2.SensitivitySettings.from_config({**cal["sensitivity"], **chosen},
                                                         n_base=int(p2.sensitivity.n_base))
    wset = sens.WeightSettings.from_config(cal["weights"])
    seed = seed_for("approach2_sensitivity")
    t0 = time.perf_counter()
    prob, res, Y = approach2.sensitivity(study_design(), rec, cal, settings, seed,
                                         bandwidth=proto.get("sensors", {}).get("force"),
                                         max_wall_s=float(p2.ga.max_wall_s), scheduler=cfg.profile.scheduler,
                                         weights=wset)
    wall = time.perf_counter() - t0
    conv = res.meta["convergence"]
    print(f"approach2_sensitivity: {conv['runs_simulated']} runs (N {conv['n_sequence']}, change per doubling "
          f"{[round(c, 3) for c in conv['change_per_doubling']]}) in {wall:.1f} s wall",
          flush=True)  # not an artifact: same config, same bytes
    W = sens.result_weights(res, prob.time, wset)
    empty = sens.unweighted_groups(res.groups, W)
    if empty:  # eq. 7.1 would score every member 0: that group's GA could not select
        raise UserError(f"approach2_sensitivity: no instant where the index of {empty} is established (weights "
                        f"rule {wset.rule!r}, N = {conv['n_final']}); raise n_max in conf/profile/"
                        f"{cfg.profile.name}.yaml approach2.sensitivity or set conf/calibration/approach2.yaml "
                        "weights.rule: estimate")
    lifts = approach2.nominal_channels(study_design(), prob, [f"lift {g} [m]" for g in res.groups],
                                       max_wall_s=float(p2.ga.max_wall_s))
    df = res.to_frame(prob.time)
    G = len(res.groups)
    labels = np.array([n for n, _ in runs(rec)], dtype=object)  # the order of the problem's cases
    df["run"] = np.tile(labels[prob.run], G)
    df["weight [-]"] = W.ravel()
    meta = {"stage": "approach2_sensitivity", "profile": cfg.profile.name, "seed": seed, "config_hash": config_hash(),
            "valve_map": valve_map(),
            "measured_seed": mmeta.get("seed"), "synthetic": bool(mmeta.get("synthetic")), **res.meta,
            "weights": {"rule": wset.rule, "clip": list(wset.clip), "smooth_s": wset.smooth_s,
                        "normalise": wset.normalise},
            "time": "training runs laid end to end [s]"}
    with staged_dir(OUT2 / "sensitivity") as tmp:
        write_frame(tmp / "indices.parquet", df, meta)
        # thesis fig. 7.6: the valve's opening (its lift above the seat; the model's lift state goes a few um
        # below 0 when the valve is closed), the intake valves' drawn with a negative sign; focus on the
        # highest force
        sign = {g: -1.0 if "intake" in g else 1.0 for g in res.groups}
        beside = {g: 1e3 * sign[g] * np.maximum(lifts[f"lift {g} [m]"], 0.0) for g in res.groups}
        tc = float(prob.time[np.argmax(np.abs(prob.measured))])
        fig = sens.figure(prob.time, res, W, prob.measured, "measured force [N]", beside,
                          "nominal opening [mm]\n(intake < 0)", (tc - FOCUS_S / 2, tc + FOCUS_S / 2),
                          f"First-order Sobol index per valve group with its bootstrap band, eq.-7.1 weight "
                          f"({wset.rule}) and the valve's opening (thesis fig. 7.6 a-d); N = {conv['n_final']}, "
                          f"{res.meta['runs']} runs, profile {cfg.profile.name}")
        fig.savefig(tmp / "sensitivity.png", dpi=90)
        plt.close(fig)
        live = ~res.masked
        write_json(tmp / "metrics.json", {
            "runs": res.meta["runs"], "n_base": settings.n_base, "failed_runs": res.meta["failed_runs"],
            "dropped_base_samples": res.meta["dropped_base_samples"],
            "masked_instants": int(res.masked.sum()), "instants": int(len(res.masked)),
            "mean_S1": {g: float(np.mean(res.S1[i, live])) for i, g in enumerate(res.groups)},
            "mean_conf": {g: float(np.mean(res.S1_conf[i, live])) for i, g in enumerate(res.groups)},
            "sum_mean_S1": float(np.sum(np.mean(res.S1[:, live], axis=1))),
            "weight_rule": wset.rule, "valve_map": meta["valve_map"],
            "zero_weight_fraction": {g: float(np.mean(W[i, live] == 0)) for i, g in enumerate(res.groups)},
            "convergence": conv})


if __name__ == "__main__":
    stage(main, "approach2_sensitivity")
