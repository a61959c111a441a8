"""Virtual-laboratory benchmark: one JSON line of figures from this run.

Runs a hidden sample (default the shipped lab-3 sample conf/lab/sample.yaml,
measured on the truth dampertwin.truth; ``--sample conf/lab/lab2/sample.yaml``
for the lab-2 path) through the lab's plan (all tests, or ``--tests``) into
a temporary folder and prints the wall time, the CPU seconds of the worker
processes, the machine's load average at the start and the end (the
machine is shared), and the CPU seconds per test (each test measured on its
own, sequentially, when ``--per-test`` is given). Issue 32's target: one
sample through all standard tests and cases <= 3 min on 2 cores.

    python bench/lab.py [--sample PATH] [--tests monosine,random] [--workers 2] [--per-test]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import tempfile
import time
from pathlib import Path

from dampertwin.lab import APPROACH2_TESTS, TRUTH_ATOL, TRUTH_RTOL, is_truth_sample, load_sample, plan, run_lab
from dampertwin.truth import TRUTH_VERSION
from dampertwin.truth.run import ATOL, RTOL

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "conf"


def children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def self_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sample", default=str(CONF / "lab" / "sample.yaml"))
    ap.add_argument("--tests", default=None)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--per-test", action="store_true")
    a = ap.parse_args()
    tests = a.tests.split(",") if a.tests else None
    items = plan(CONF)
    sample = Path(a.sample)
    truth = is_truth_sample(load_sample(sample))
    out = {"sample": sample.name, "truth": TRUTH_VERSION if truth else "model (lab 2)",
           "truth_rtol": RTOL if truth else TRUTH_RTOL, "truth_atol": ATOL if truth else TRUTH_ATOL,
           "workers": a.workers, "load_start": round(os.getloadavg()[0], 2)}
    with tempfile.TemporaryDirectory() as tmp:
        c0, w0 = children_cpu() + self_cpu(), time.perf_counter()
        files = run_lab(sample, tmp, tests=tests, conf=CONF, workers=a.workers, progress=False)
        out["wall_s"] = round(time.perf_counter() - w0, 1)
        out["cpu_s"] = round(children_cpu() + self_cpu() - c0, 1)
        out["files"] = len(files)
        out["load_end"] = round(os.getloadavg()[0], 2)
    out["standard_files"] = sum(1 for t, _ in items if t not in APPROACH2_TESTS)
    if a.per_test:
        per = {}
        for t in sorted({t for t, _ in items if tests is None or t in tests}):
            with tempfile.TemporaryDirectory() as tmp:
                c0 = self_cpu()
                run_lab(sample, tmp, tests=[t], conf=CONF, workers=1, progress=False)
                per[t] = round(self_cpu() - c0, 1)
        out["cpu_s_per_test"] = per
    print(json.dumps(out))


if __name__ == "__main__":
    main()
