"""Approach-2 benchmark (issue 12): one JSON line.

- cost of one training evaluation: the nominal design through the whole
  damper-level training signal (conf/test/training.yaml, all currents, one
  simulation per current) [s wall and CPU of the integrating thread], on
  the protocol's clean excitation and, when the lab's record is present
  (``--measured``), driven by its recorded displacement through the
  approach-2 input low-pass as the stages do (transducer noise included:
  the cost the full profile pays; the full-profile estimates use it);
- the sensitivity stage time: ``calibration.approach2.sensitivity`` (the
  stage's code) timed on a training record made from the nominal design's
  own simulation (no measured data needed) with the ci profile's settings
  (run I1.6, last 1.95 s, ``--n-base`` 4 -> 40 runs), and the full-profile
  estimate 320 runs x cost / (2 x efficiency);
- parallel efficiency on 2 local workers: a batch of GA-like members
  (parameters drawn in the approach-2 search windows, seeded) through one
  training run on 1 and on 2 numba threads, eff = T1 / (2 T2).

    python bench/approach2.py [--batch 4] [--run I1.6] [--seed 1] [--n-base 4] [--measured data/measured]

A busy machine lowers the efficiency: compare wall with CPU seconds.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numba
import numpy as np
import pandas as pd

from dampertwin.calibration import approach2 as a2
from dampertwin.calibration import sensitivity as sens
from dampertwin.design import load, yaml_load_file
from dampertwin.io import read_frame
from dampertwin.protocols import build_runs, load_protocol
from dampertwin.simulation import simulate, simulate_batch

ROOT = Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--batch", type=int, default=4, help="members of the 1- vs 2-thread batch")
    ap.add_argument("--run", default="I1.6", help="training run of the parallel-efficiency batch")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--n-base", type=int, default=4, help="sensitivity base samples (ci profile: 4)")
    ap.add_argument("--tail", type=float, default=1.95, help="sensitivity record: last seconds of the run (ci: 1.95)")
    ap.add_argument("--measured", default=str(ROOT / "data" / "measured"),
                    help="measurement folder with training/baseline.parquet (the recorded-input cost)")
    a = ap.parse_args()
    d = load(ROOT / "conf/design/baseline.yaml")
    proto = load_protocol(ROOT / "conf/test/training.yaml")
    runs = build_runs(proto, 0)
    t0, c0 = time.perf_counter(), time.thread_time()
    for r in runs:
        res = simulate(d, r.excitation, "damper", current=r.current, rate=r.rate)
        assert res.ok, res.stats.message
    eval_wall, eval_cpu = time.perf_counter() - t0, time.thread_time() - c0

    cal = yaml_load_file(ROOT / "conf/calibration/approach2.yaml")
    recorded = Path(a.measured) / "training" / "baseline.parquet"
    rec_cost = None
    if recorded.is_file():  # as the stages do: recorded displacement through the approach-2 input low-pass
        df, _ = read_frame(recorded)
        cases = a2.damper_cases(a2.check_damper_record(df, str(recorded)), a2.input_cutoff(cal, {"training": proto}))
        t0, c0 = time.perf_counter(), time.thread_time()
        for t, _, ex, extra in cases:
            res = simulate(d, ex, "damper", current=extra["current"], rate=1.0 / float(t[1] - t[0]))
            assert res.ok, res.stats.message
        rec_cost = (time.perf_counter() - t0, time.thread_time() - c0)
    groups, comp = a2.groups_from_config(d, cal)
    specs = [s for g in groups + [comp] for s in g.specs]
    rng = np.random.default_rng(a.seed)
    G = np.clip(np.array([s.to_gene(d[s.key]) for s in specs]) + 0.1 * rng.standard_normal((a.batch, len(specs))), 0, 1)
    designs = [d.with_overrides({s.key: float(s.to_value(g[j])) for j, s in enumerate(specs)}) for g in G]
    run = next(r for r in runs if r.name == a.run)
    times = {}
    for threads in (1, 2):
        numba.set_num_threads(threads)
        t0 = time.perf_counter()
        _, _, status = simulate_batch(designs, run.excitation, "damper", current=run.current, rate=run.rate,
                                      channels=["rod force [N]"])
        times[threads] = time.perf_counter() - t0
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    eff = times[1] / (2 * times[2])

    n_full = sens.runs_needed(32, len(groups))
    out = {
        "training_eval_wall_s": round(eval_wall, 3), "training_eval_cpu_s": round(eval_cpu, 3),
        "training_eval_recorded_wall_s": None if rec_cost is None else round(rec_cost[0], 3),
        "training_eval_recorded_cpu_s": None if rec_cost is None else round(rec_cost[1], 3),
        "estimates_from": "clean protocol excitation" if rec_cost is None else f"recorded input ({recorded})",
        "training_runs": len(runs), "training_simulated_s": round(sum(r.excitation.t_end - r.excitation.t0
                                                                      for r in runs), 3),
        "batch": a.batch, "batch_failed": int(np.sum(status != 0)),
        "batch_wall_1_thread_s": round(times[1], 3), "batch_wall_2_threads_s": round(times[2], 3),
        "parallel_efficiency_2_workers": round(eff, 3),
        "sensitivity_full_runs": n_full,
    }
    ew, ec = (eval_wall, eval_cpu) if rec_cost is None else rec_cost
    ga = yaml_load_file(ROOT / "conf/profile/full.yaml")["approach2"]["ga"]
    n_fit = int(ga["population"]) * (int(ga["generations"]) + 1)  # full profile: the initial population + generations
    out.update({
        "sensitivity_full_estimate_s": round(n_full * ew / (2 * eff), 1),  # at this run's load
        "sensitivity_full_estimate_idle_s": round(n_full * ec / (2 * eff), 1),  # CPU basis: an idle machine
        "fit_full_estimate_idle_s": round(n_fit * ec / (2 * eff), 1),
    })
    # the sensitivity stage's code on a record made from the nominal design's own simulation
    r = simulate(d, run.excitation, "damper", current=run.current, rate=run.rate)
    rec = pd.DataFrame({"time [s]": r.time, "displacement [m]": r["displacement [m]"],
                        "force [N]": r["rod force [N]"], "current [A]": run.current, "run": run.name})
    rec = a2.check_damper_record(rec, "bench record", [run.name], a.tail)
    st = a2.SensitivitySettings.from_config(cal["sensitivity"], n_base=a.n_base)
    t0 = time.perf_counter()
    _, res, _ = a2.sensitivity(d, rec, cal, st, a.seed, bandwidth=proto.get("sensors", {}).get("force"),
                               max_wall_s=600.0, progress=False)
    out["sensitivity_runs"] = res.meta["runs"]
    out["sensitivity_tail_s"] = a.tail
    out["sensitivity_wall_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
