"""DVC stage `approach2_fit`: concurrent sensitivity-weighted GAs (thesis
Algorithm 1, eq. 7.1) on the damper-level training record: one GA per valve
(weights from approach2_sensitivity) over the parameters the
approach2_identifiability stage found determined (the others stay at the
drawings' values; a valve with none has no GA), one unweighted for gas
content and oil bulk modulus; best solution by the unweighted residual. Outputs
results/approach2/fit/: overlay.yaml, history.parquet, metrics.json,
progress.png (like fig. 7.7), training.png (force, measured vs fitted)."""

import time

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from _approach2 import OUT2, damper_record, profile_block
from _common import CONF, study_design, valve_map, config_hash, seed_for, stage, staged_dir, write_json, write_overlay
from dampertwin.calibration import approach2
from dampertwin.calibration.concurrent import progress_figure
from dampertwin.calibration.ga import GASettings
from dampertwin.checkpoint import NpzStore
from dampertwin.design import yaml_load_file
from dampertwin.errors import UserError
from dampertwin.io import write_frame


def decision() -> tuple[list[str], list[str]]:
    """(valve parameters to fit, those fixed at the drawings' values) of the
    approach2_identifiability stage."""
    import json

    src = OUT2 / "identifiability" / "determined.json"
    if not src.is_file():
        raise UserError(f"{src}: not found; run the approach2_identifiability stage first")
    doc = json.loads(src.read_text())
    if not isinstance(doc.get("determined"), list) or not isinstance(doc.get("fixed"), list):
        raise UserError(f"{src}: expected lists 'determined' and 'fixed' of valve parameter keys; rerun the "
                        "approach2_identifiability stage")
    return list(doc["determined"]), list(doc["fixed"])


def main() -> None:
    cfg, p2 = profile_block()
    cal = yaml_load_file(CONF / "calibration" / "approach2.yaml")
    rec, proto, mmeta = damper_record("training", p2.runs, p2.get("tail_s"))
    approach2.input_cutoff(cal, {"training": proto})  # a corner that would filter the motion: a clear error
    src = OUT2 / "sensitivity" / "indices.parquet"
    if not src.is_file():
        raise UserError(f"{src}: not found; run the approach2_sensitivity stage first")
    ind = pd.read_parquet(src)  # this pipeline's own artifact (NaN where masked): no measured-data checks
    groups = list(dict.fromkeys(ind["group"]))
    W = np.vstack([ind.loc[ind["group"] == g, "weight [-]"].to_numpy() for g in groups])
    free, fixed = decision()
    settings = GASettings.from_config(p2.ga)
    seed = seed_for("approach2_fit")
    d = study_design()
    ck = NpzStore(OUT2 / "checkpoints" / "approach2_fit.npz")  # the stage owns the file; the GAs see a store
    t0 = time.perf_counter()
    res, prob = approach2.fit(d, rec, cal, W, groups, settings, seed, bandwidth=proto.get("sensors", {}).get("force"),
                              checkpoint=ck, scheduler=cfg.profile.scheduler, free=free)
    wall = time.perf_counter() - t0
    print(f"approach2_fit: {res.evaluations} evaluations in {wall:.1f} s wall "
          f"({wall / max(res.evaluations, 1):.2f} s each)", flush=True)  # not an artifact: same config, same bytes
    meta = {"fit": "approach2_fit", "profile": cfg.profile.name, "seed": seed, "config_hash": config_hash(),
            "valve_map": valve_map(),
            "objective": "Algorithm 1: eq. 7.1 per valve group, unweighted int|F_test - F_sim| dt [N*s] for the "
                         "compliance group and the best solution"}
    with staged_dir(OUT2 / "fit") as tmp:
        write_overlay(tmp / "overlay.yaml", res.best, meta)
        write_frame(tmp / "history.parquet", res.history, {**meta, "design_hash": d.hash()})
        write_json(tmp / "metrics.json", {
            "objective_start": res.start_objective, "objective_best": res.best_objective,
            "improvement_pct": 100 * (1 - res.best_objective / res.start_objective),
            "group_objectives_best": res.best_group_objectives, "best_evaluation": res.best_evaluation,
            "evaluations": res.evaluations, "failed_simulations": res.failed, "failure_reasons": res.failures,
            "values": res.best, "bound_hits": res.bound_hits, "fitted_valve_parameters": free,
            "valve_map": meta["valve_map"],
            "fixed_at_drawings": {k: float(d[k]) for k in fixed},
            "identifiability": "results/approach2/identifiability/determined.json (identifiability.png)"})
        fig = progress_figure(res.history, res.groups, f"Concurrent GAs, profile {cfg.profile.name} (thesis fig. 7.7)")
        fig.savefig(tmp / "progress.png", dpi=100)
        plt.close(fig)
        X = np.array([[res.best[s.key] for s in prob.specs], [d[s.key] for s in prob.specs]])
        F = prob.simulated(X)
        fig, ax = plt.subplots(figsize=(12, 4.5), constrained_layout=True)
        ax.plot(prob.time, prob.measured, lw=0.7, label="measured (SYNTHETIC lab)" if mmeta.get("synthetic") else "measured")
        ax.plot(prob.time, F[1], ":", lw=0.7, label="nominal design")
        ax.plot(prob.time, F[0], "--", lw=0.7, label="approach 2 fit")
        ax.set(xlabel="time [s] (training runs end to end)", ylabel="damper force [N]",
               title="Training signal, damper level (thesis fig. 7.9)")
        ax.legend()
        ax.grid(alpha=0.3)
        fig.savefig(tmp / "training.png", dpi=100)
        plt.close(fig)
    ck.path.unlink(missing_ok=True)


if __name__ == "__main__":
    stage(main, "approach2_fit")
