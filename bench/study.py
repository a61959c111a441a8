"""The study's fits under the default profile (`full`: the thesis' GA
budgets, approach 2's first-order Sobol design) against `thesis` (its
second-order Saltelli design) on
the same lab records, in ONE run: one JSON line (with ``--stall``, also the
default with every GA stopping on convergence).

A reduced set (issue 39): the `flowbench_fit@piston_rebound`,
`compliance_fit` and `topmount_fit@baseline` stage code (GA + polish, the
stages' seeds, the profile's budgets; the compliance fit on the nominal
valves, not the fitted ones) and approach 2 (sensitivity + the
concurrent GAs) on the ci profile's training selection (run I1.6, its last
1.95 s) with each profile's sensitivity design and GA. Per part and
profile: wall and CPU seconds, evaluations (simulations), final objective;
then the ratios full / thesis.

    PYTHONPATH=src python bench/study.py --measured data/measured [--parts valve,compliance,topmount,approach2]
        [--stall 8:1e-3] [--seed-offset N]

CPU seconds are the process's (all threads). The machine is shared while
sessions work: compare ratios and evaluations, which the load does not move.
"""

from __future__ import annotations

import argparse
import json
import time
import zlib
from pathlib import Path

import numpy as np

from dampertwin.calibration import approach2
from dampertwin.calibration import sensitivity as sens
from dampertwin.calibration.approach1 import fit_compliance, fit_top_mount, fit_valve
from dampertwin.calibration.approach2 import check_damper_record
from dampertwin.calibration.ga import GASettings
from dampertwin.calibration.polish import PolishSettings
from dampertwin.design import load, yaml_load_file
from dampertwin.io import read_frame, read_record
from dampertwin.protocols import load_protocol

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "conf"
PARTS = ("valve", "compliance", "topmount", "approach2")


def _timed(fn):
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


SEED_OFFSET = 0  # --seed-offset: other seeds than the stages' (the GAs' run-to-run scatter)


def _seed(name: str) -> int:
    """The stages' seed for a stage name (stages/_common.py seed_for), plus ``SEED_OFFSET``."""
    return (int(yaml_load_file(CONF / "config.yaml").get("seed", 0)) + zlib.crc32(name.encode()) + SEED_OFFSET) % 2**31


def _valve(prof: dict, d, meas: Path):
    fb = load_protocol(CONF / "test" / "flowbench.yaml")
    rec = read_frame(meas / "flowbench" / "piston_rebound.parquet", "flowbench")[0]
    return fit_valve(d, "piston_rebound", rec, yaml_load_file(CONF / "calibration" / "valves.yaml"),
                     GASettings.from_config(prof["ga"]["valves"]), _seed("flowbench_fit/piston_rebound"),
                     bench={"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]},
                     progress=False, polish_settings=PolishSettings.from_config(prof["polish"], "valves"))


def _compliance(prof: dict, d, meas: Path):
    rec, _ = read_record(meas / "compliance" / "baseline.parquet", "compliance", conf=CONF)
    proto = load_protocol(CONF / "test" / "compliance.yaml")
    return fit_compliance(d, rec, yaml_load_file(CONF / "calibration" / "compliance.yaml"),
                          GASettings.from_config(prof["ga"]["compliance"]), _seed("compliance_fit"), progress=False,
                          polish_settings=PolishSettings.from_config(prof["polish"]),
                          force_bandwidth=proto.get("sensors", {}).get("force"))


def _topmount(prof: dict, d, meas: Path):
    rec = read_frame(meas / "topmount" / "baseline.parquet", "topmount")[0]
    proto = load_protocol(CONF / "test" / "topmount.yaml")
    res, _, _ = fit_top_mount(d, rec, yaml_load_file(CONF / "calibration" / "topmount.yaml"),
                              GASettings.from_config(prof["ga"]["topmount"]), _seed("topmount_fit/baseline"),
                              progress=False, polish_settings=PolishSettings.from_config(prof["polish"]),
                              force_bandwidth=proto.get("sensors", {}).get("force"))
    return res


def _approach2(prof: dict, d, meas: Path):
    """Sensitivity (the profile's N and design) then the concurrent GAs on
    the ci profile's training selection."""
    ci = yaml_load_file(CONF / "profile" / "ci.yaml")["approach2"]
    cal = yaml_load_file(CONF / "calibration" / "approach2.yaml")
    p2 = prof["approach2"]
    proto = load_protocol(CONF / "test" / "training.yaml")
    df, _ = read_record(meas / "training" / "baseline.parquet")
    rec = check_damper_record(df, "training", list(ci["runs"]), ci["tail_s"])
    chosen = {k: v for k, v in p2["sensitivity"].items() if k == "second_order"}
    s = approach2.SensitivitySettings.from_config({**cal["sensitivity"], **chosen}, n_base=int(p2["sensitivity"]["n_base"]))
    bw = proto.get("sensors", {}).get("force")
    ga = GASettings.from_config(p2["ga"])
    prob, sres, _ = approach2.sensitivity(d, rec, cal, s, _seed("approach2_sensitivity"), bandwidth=bw,
                                          max_wall_s=float(ga.max_wall_s), progress=False)
    W = sens.result_weights(sres, prob.time, sens.WeightSettings.from_config(cal["weights"]))
    res, _ = approach2.fit(d, rec, cal, W, list(sres.groups), ga, _seed("approach2_fit"), bandwidth=bw,
                           progress=False)
    res.evaluations += int(sres.meta["runs"])
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--measured", default=str(ROOT / "data" / "measured"), help="lab records (flowbench/, ...)")
    ap.add_argument("--parts", default=",".join(PARTS), help=f"comma-separated subset of {', '.join(PARTS)}")
    ap.add_argument("--stall", default=None, metavar="K:TOL",
                    help="also run profile full with every GA stopping after K generations that gained <= TOL "
                         "(relative): the convergence-stop lever")
    ap.add_argument("--seed-offset", type=int, default=0,
                    help="add this to every stage seed (0: the study's seeds); several offsets give the scatter")
    a = ap.parse_args()
    global SEED_OFFSET
    SEED_OFFSET = a.seed_offset
    parts = [p for p in a.parts.split(",") if p]
    bad = [p for p in parts if p not in PARTS]
    if bad:
        ap.error(f"--parts: unknown {', '.join(bad)}; expected {', '.join(PARTS)}")
    meas = Path(a.measured)
    d = load(CONF / "design" / "baseline.yaml")
    fns = {"valve": _valve, "compliance": _compliance, "topmount": _topmount, "approach2": _approach2}
    out: dict = {"bench": "study", "measured": str(meas), "seed_offset": SEED_OFFSET}
    variants = {name: yaml_load_file(CONF / "profile" / f"{name}.yaml") for name in ("full", "thesis")}
    if a.stall:
        k, tol = a.stall.split(":")
        full = variants["full"]
        stall = {"stall_generations": int(k), "stall_tol": float(tol)}
        variants["stall"] = {**full, "ga": {b: {**g, **stall} for b, g in full["ga"].items()},
                             "approach2": {**full["approach2"], "ga": {**full["approach2"]["ga"], **stall}}}
        out["stall"] = stall
    for part in parts:
        for name, prof in variants.items():
            res, w, c = _timed(lambda: fns[part](prof, d, meas))
            out[f"{part} {name}"] = {"wall [s]": round(w, 2), "cpu [s]": round(c, 2), "evaluations": res.evaluations,
                                     "objective": res.best_objective,
                                     "generations": int(len(res.history) - 1)}
        t = out[f"{part} thesis"]
        for name in [v for v in variants if v != "thesis"]:
            f = out[f"{part} {name}"]
            out[f"{part} {name}/thesis"] = {"wall": round(f["wall [s]"] / t["wall [s]"], 3),
                                            "evaluations": round(f["evaluations"] / t["evaluations"], 3),
                                            "objective": round(f["objective"] / t["objective"], 4)}
    out["total full/thesis wall"] = round(float(np.sum([out[f"{p} full"]["wall [s]"] for p in parts])
                                          / np.sum([out[f"{p} thesis"]["wall [s]"] for p in parts])), 3)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
