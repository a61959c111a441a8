"""Same physics check (issue 9, acceptance 5): the approach-1 KPIs of the
baseline design (table 6.5: rod-acceleration peaks of the 13 Hz mono-sine;
table 6.6: PSD at 200 / 300 Hz of the random test; at 0.32 / 0.9 / 1.6 A)
at the default solver settings against rtol 1e-8, and optionally against
another checkout of dampertwin (``--other SRC``: run it there with
PYTHONPATH=SRC to compare cores). One JSON line; ``--save FILE`` keeps the
KPIs for a later ``--compare FILE``.

    python bench/same_physics.py [--save kpis.json] [--compare kpis.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from dampertwin import simulate
from dampertwin.design import load
from dampertwin.kpi import psd_levels, rod_acceleration_peaks
from dampertwin.protocols import build_runs, load_protocol

ROOT = Path(__file__).resolve().parents[1]


def kpis(design, rtol=None):
    out = {}
    for test in ("monosine", "random"):
        proto = load_protocol(ROOT / "conf" / "test" / f"{test}.yaml")
        for run in build_runs(proto, seed=0):
            kw = {} if rtol is None else {"rtol": rtol, "method": "rodas4"}  # the tight reference: order 4
            r = simulate(design, run.excitation, run.configuration, current=run.current, rate=run.rate, **kw)
            df = r.to_frame()
            if test == "monosine":
                pk = rod_acceleration_peaks(df, proto["frequency"])
                out.update({f"{test}@{run.current}:{k} [g]": v for k, v in pk.items()})
                last = r.time >= r.time[-1] - 1 / proto["frequency"]
                out[f"{test}@{run.current}:F max [N]"] = float(r["rod force [N]"][last].max())
                out[f"{test}@{run.current}:F min [N]"] = float(r["rod force [N]"][last].min())
            else:
                lv = psd_levels(df)
                out.update({f"{test}@{run.current}:{k}": v for k, v in lv.items() if k.endswith("[dB]")})
    return out


def deviation(a: dict, b: dict) -> dict:
    """Per KPI: relative deviation [%] (dB values: absolute [dB])."""
    dev = {}
    for k in a:
        if k.endswith("[dB]"):
            dev[k] = abs(a[k] - b[k])
        else:
            dev[k] = abs(a[k] - b[k]) / max(abs(b[k]), 1e-12) * 100
    return dev


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--save")
    ap.add_argument("--compare")
    ap.add_argument("--no-tight", action="store_true")
    a = ap.parse_args()
    d = load(ROOT / "conf/design/baseline.yaml")
    k = kpis(d)
    res = {}
    if not a.no_tight:
        tight = kpis(d, rtol=1e-8)
        dv = deviation(k, tight)
        res["vs_rtol_1e-8_max_pct"] = round(max(v for kk, v in dv.items() if not kk.endswith("[dB]")), 4)
        res["vs_rtol_1e-8_max_dB"] = round(max(v for kk, v in dv.items() if kk.endswith("[dB]")), 4)
    if a.compare:
        other = json.loads(Path(a.compare).read_text())
        dv = deviation(k, other)
        worst = max((v, kk) for kk, v in dv.items() if not kk.endswith("[dB]"))
        res["vs_saved_max_pct"] = round(worst[0], 4)
        res["vs_saved_worst"] = worst[1]
        res["vs_saved_max_dB"] = round(max(v for kk, v in dv.items() if kk.endswith("[dB]")), 4)
    if a.save:
        Path(a.save).write_text(json.dumps(k, indent=1))
    res["kpis"] = len(k)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
