"""Input low-pass of the damper-level records (issue 12): one JSON line.

Each run of the measured training and verification records driven by its
recorded displacement, low-passed (zero-phase, ``Excitation.from_samples``)
at each corner given, through the nominal design: the residual
int |F_meas - F_sim| dt [N s] (simulated force through the documented
load-cell bandwidth), solver steps and CPU seconds of the integrating
thread, summed over the runs (three currents). Needs the lab's records
(``dvc repro lab`` or ``--measured``).

    python bench/input_cutoff.py [--measured data/measured] [--cutoffs 1000,200]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from dampertwin import Excitation, simulate
from dampertwin.design import load
from dampertwin.io import read_frame, runs
from dampertwin.protocols import load_protocol
from dampertwin.sensors import sensor_lowpass

ROOT = Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--measured", default=str(ROOT / "data" / "measured"))
    ap.add_argument("--cutoffs", default="1000,200", help="corners [Hz], comma separated")
    a = ap.parse_args()
    design = load(ROOT / "conf" / "design" / "baseline.yaml")
    out = {"design": "conf/design/baseline.yaml (nominal)", "measured": a.measured}
    for test in ("training", "verification"):
        df, _ = read_frame(Path(a.measured) / test / "baseline.parquet")
        bw = load_protocol(ROOT / "conf" / "test" / f"{test}.yaml").get("sensors", {}).get("force")
        for cut in (float(c) for c in a.cutoffs.split(",")):
            res = steps = cpu = 0.0
            for _, g in runs(df):
                t = g["time [s]"].to_numpy() - float(g["time [s]"].iloc[0])
                fs = 1.0 / float(np.mean(np.diff(t)))
                ex = Excitation.from_samples(t, g["displacement [m]"].to_numpy(), cutoff=cut)
                c0 = time.thread_time()
                r = simulate(design, ex, "damper", current=float(g["current [A]"].iloc[0]), rate=fs)
                cpu += time.thread_time() - c0
                if not r.ok:
                    raise RuntimeError(f"{test}: simulation failed at {cut:g} Hz: {r.stats.message}")
                fsim = sensor_lowpass(r["rod force [N]"], bw, fs)
                n = min(len(fsim), len(t))
                res += float(np.trapezoid(np.abs(g["force [N]"].to_numpy()[:n] - fsim[:n]), t[:n]))
                steps += r.stats.steps
            out[f"{test}_{cut:g}Hz"] = {"residual_Ns": round(res, 1), "steps": int(steps), "cpu_s": round(cpu, 2)}
        lo, hi = out[f"{test}_{min(map(float, a.cutoffs.split(','))):g}Hz"], \
            out[f"{test}_{max(map(float, a.cutoffs.split(','))):g}Hz"]
        out[f"{test}_residual_ratio_high_over_low"] = round(hi["residual_Ns"] / lo["residual_Ns"], 3)
        out[f"{test}_steps_ratio_high_over_low"] = round(hi["steps"] / lo["steps"], 2)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
