"""Approach-1 fit stages' code in the ci profile (issue 33): one JSON line.

Runs the code of `flowbench_fit@piston_rebound` and `topmount_fit@baseline`
(calibration.approach1 with the ci profile's GA and polish budgets and the
stages' seeds) on lab records (``--measured``, e.g. from ``dampertwin lab
--tests flowbench,topmount``), and, when this checkout has it, the
identifiable quantities the stages now add (valve lift-force curve, top-mount
dynamic stiffness). Prints wall and CPU seconds per part and a hash of the
fitted values, so two checkouts can be compared for speed and for
bit-identical results:

    PYTHONPATH=src python bench/fits.py --measured /tmp/lab
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time
import zlib
from pathlib import Path

from dampertwin.calibration.approach1 import fit_top_mount, fit_valve
from dampertwin.calibration.ga import GASettings
from dampertwin.calibration.polish import PolishSettings
from dampertwin.design import load, yaml_load_file
from dampertwin.io import read_frame
from dampertwin.protocols import load_protocol

ROOT = Path(__file__).resolve().parents[1]


def _timed(fn):
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, round(time.perf_counter() - w, 3), round(time.process_time() - c, 3)


def _hash(d: dict) -> str:
    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--measured", required=True, help="folder with flowbench/ and topmount/ records")
    a = ap.parse_args()
    meas = Path(a.measured)
    prof = yaml_load_file(ROOT / "conf" / "profile" / "ci.yaml")
    d = load(ROOT / "conf" / "design" / "baseline.yaml")
    polish = PolishSettings.from_config(prof["polish"])
    seed = int(yaml_load_file(ROOT / "params.yaml").get("seed", 0))
    out = {"bench": "fits", "profile": "ci"}
    fb = load_protocol(ROOT / "conf" / "test" / "flowbench.yaml")
    bench = {"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]}
    rec = read_frame(meas / "flowbench" / "piston_rebound.parquet", "flowbench")[0]
    res, w, c = _timed(lambda: fit_valve(d, "piston_rebound", rec, yaml_load_file(ROOT / "conf" / "calibration" /
                                         "valves.yaml"), GASettings.from_config(prof["ga"]["valves"]),
                                         (seed + zlib.crc32(b"flowbench_fit/piston_rebound")) % 2**31, bench=bench,
                                         progress=False, polish_settings=polish))
    out.update({"valve wall [s]": w, "valve cpu [s]": c, "valve values": _hash(res.best),
                "valve objective": res.best_objective})
    tm = read_frame(meas / "topmount" / "baseline.parquet", "topmount")[0]
    proto = load_protocol(ROOT / "conf" / "test" / "topmount.yaml")
    (tres, coef, _), w, c = _timed(lambda: fit_top_mount(
        d, tm, yaml_load_file(ROOT / "conf" / "calibration" / "topmount.yaml"),
        GASettings.from_config(prof["ga"]["topmount"]), (seed + zlib.crc32(b"topmount_fit/baseline")) % 2**31,
        progress=False, polish_settings=polish, force_bandwidth=proto.get("sensors", {}).get("force")))
    out.update({"topmount wall [s]": w, "topmount cpu [s]": c, "topmount values": _hash(tres.best),
                "topmount objective": tres.best_objective})
    try:
        from dampertwin.calibration.identifiability import sweep_points, top_mount_report, valve_report
    except ImportError:
        print(json.dumps(out))
        return
    _, w, c = _timed(lambda: valve_report(d.with_overrides(res.best), "piston_rebound", res.uncertainty, res.specs,
                                          2e-4))
    out.update({"valve determined wall [s]": w, "valve determined cpu [s]": c})
    _, w, c = _timed(lambda: top_mount_report(d.with_overrides({"top_mount.F_LD": coef}), tres.best,
                                              tres.uncertainty, tres.specs, *sweep_points(proto)))
    out.update({"topmount determined wall [s]": w, "topmount determined cpu [s]": c})
    print(json.dumps(out))


if __name__ == "__main__":
    main()
