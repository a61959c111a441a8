"""Solver benchmark: one JSON line of figures and ratios measured in this run.

Module model, all effects on, 13 Hz / 10 mm mono-sine at 1.6 A, 1 s simulated:
compiled Rodas4 (median of N runs) vs the reference path (plain-Python RHS
under scipy BDF), a 64-member batch on 1 and 2 threads, and the KPI deviation
of the default tolerance from a tight-tolerance run.

    python bench/solver.py [--repeats 3] [--batch 64]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numba
import numpy as np

from dampertwin import Excitation, simulate, simulate_batch
from dampertwin.design import load
from dampertwin.reference import simulate_reference

ROOT = Path(__file__).resolve().parents[1]


def peaks(r, f=13.0):
    m = r.time >= r.time[-1] - 1.0 / f
    F, a = r["rod force [N]"][m], r["rod acceleration [m/s^2]"][m]
    return np.array([F.max(), -F.min(), a.max(), -a.min()])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    d = load(ROOT / "conf/design/baseline.yaml")
    sim_s = 1.0
    ex = Excitation.sine(0.005, 13.0, sim_s)
    simulate(d, Excitation.sine(0.005, 13.0, 0.05), "module")  # compile / load cache

    walls, res = [], None
    for _ in range(a.repeats):
        t0 = time.perf_counter()
        res = simulate(d, ex, "module", current=1.6)
        walls.append(time.perf_counter() - t0)
    wall = statistics.median(walls)
    tight = simulate(d, ex, "module", current=1.6, rtol=1e-8)
    kpi_dev = float(np.max(np.abs(peaks(res) - peaks(tight)) / np.abs(peaks(tight))) * 100)

    naive = [simulate_reference(d, ex, "module", current=1.6, rtol=1e-4).stats.wall_s for _ in range(a.repeats)]
    naive_wall = statistics.median(naive)

    rng = np.random.default_rng(a.seed)
    keys = [p.key for p in d.by_type("C") if p.group in ("piston_rebound", "base_compression") and p.name in ("a", "c")]
    pop = [d.with_overrides({k: d[k] * rng.uniform(0.8, 1.2) for k in keys}) for _ in range(a.batch)]
    times = {}
    for threads in (1, 2):
        numba.set_num_threads(threads)
        simulate_batch(pop[:2], Excitation.sine(0.005, 13.0, 0.02), "module")  # warm
        t0 = time.perf_counter()
        _, _, status = simulate_batch(pop, ex, "module", channels=["rod force [N]"])
        times[threads] = time.perf_counter() - t0
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    print(json.dumps({
        "sim_s": sim_s,
        "wall_s": round(wall, 4),
        "realtime_factor": round(sim_s / wall, 2),
        "steps": res.stats.steps,
        "naive_wall_s": round(naive_wall, 3),
        "speedup_vs_naive": round(naive_wall / wall, 1),
        "batch_members": a.batch,
        "batch_wall_1_thread_s": round(times[1], 3),
        "batch_wall_2_threads_s": round(times[2], 3),
        "batch_speedup_2_threads": round(times[1] / times[2], 2),
        "batch_failed": int(np.sum(status != 0)),
        "kpi_deviation_pct": round(kpi_dev, 4),
        "rtol": 1e-4,
    }))


if __name__ == "__main__":
    main()
