"""DVC stage `approach2_identifiability`: which of each valve group's
table-6.1 parameters (conf/calibration/approach2.yaml ``parameters``) the
damper-level training record determines, at the drawings' values, each group
on its eq.-7.1-weighted residual (weights from approach2_sensitivity;
calibration.determined, rule in ``identifiability``). The approach2_fit
stage fits the determined ones; the others stay at the drawings' values.
Outputs results/approach2/identifiability/: determined.json (the decision,
per group: determined, fixed, each step and the intervals / correlations),
identifiability.png (relative 95 % half-widths and correlations), report.md."""

import time

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from _approach2 import OUT2, damper_record, profile_block
from _common import CONF, study_design, config_hash, stage, staged_dir, write_json, write_text
from dampertwin.calibration import approach2
from dampertwin.calibration.determined import Rule, figure, summary
from dampertwin.design import yaml_load_file
from dampertwin.errors import UserError


def weights():
    """(W (G, n), group names) of the sensitivity stage's output."""
    src = OUT2 / "sensitivity" / "indices.parquet"
    if not src.is_file():
        raise UserError(f"{src}: not found; run the approach2_sensitivity stage first")
    ind = pd.read_parquet(src)  # this pipeline's own artifact (NaN where masked)
    groups = list(dict.fromkeys(ind["group"]))
    return np.vstack([ind.loc[ind["group"] == g, "weight [-]"].to_numpy() for g in groups]), groups


def report(dec: dict, rule: Rule, profile: str) -> str:
    lines = [f"# Approach 2: which valve parameters the training record determines (profile {profile})\n",
             f"Rule: 95 % half-width < {rule.rel_ci_max:.0%} of the value and |corr| < {rule.corr_max:g} with "
             "every other fitted parameter, each group on its eq.-7.1-weighted residual at the drawings' values; "
             "parameters join in the orthogonal method's order (calibration.determined). Figure: "
             "identifiability.png.\n", "| group | fitted | fixed at the drawings' value |", "|---|---|---|"]
    for g, d in dec.items():
        lines.append(f"| {g} | {', '.join(k.split('.')[-1] for k in d['determined']) or '-'} | "
                     f"{', '.join(k.split('.')[-1] for k in d['fixed']) or '-'} |")
    lines.append("\nWhy each fixed one was left out (analysed with those chosen before it; the flags of that "
                 "analysis):\n")
    for g, d in dec.items():
        for s in d["steps"]:
            if not s["joins"]:
                lines.append(f"- tried {s['parameter']}: {s['why not']}")
    return "\n".join(lines) + "\n"


def main() -> None:
    cfg, p2 = profile_block()
    cal = yaml_load_file(CONF / "calibration" / "approach2.yaml")
    rec, proto, _ = damper_record("training", p2.runs, p2.get("tail_s"))
    approach2.input_cutoff(cal, {"training": proto})
    W, groups = weights()
    t0 = time.perf_counter()
    dec, _ = approach2.identifiability(study_design(), rec, cal, W, groups, bandwidth=proto.get("sensors", {}).get("force"),
                                       max_wall_s=float(p2.ga.max_wall_s))
    print(f"approach2_identifiability: {time.perf_counter() - t0:.1f} s wall", flush=True)  # not an artifact
    rule = Rule.from_config(cal["identifiability"])
    with staged_dir(OUT2 / "identifiability") as tmp:
        write_json(tmp / "determined.json", {**summary(dec, rule), "profile": cfg.profile.name,
                                             "config_hash": config_hash(),
                                             "determined": [k for d in dec.values() for k in d["determined"]],
                                             "fixed": [k for d in dec.values() for k in d["fixed"]]})
        fig = figure(dec, rule, "Approach 2: valve parameters on the training record at the drawings' values "
                                f"(profile {cfg.profile.name})")
        fig.savefig(tmp / "identifiability.png", dpi=100)
        plt.close(fig)
        write_text(tmp / "report.md", report(dec, rule, cfg.profile.name))


if __name__ == "__main__":
    stage(main, "approach2_identifiability")
