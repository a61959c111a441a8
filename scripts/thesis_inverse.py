"""The unpublished design values estimated from the thesis' own simulated
results (issue 40, acceptance item 2): a STUDY, the baseline is not changed.

The data are the thesis' simulated columns of tables 6.5, 6.6, 7.1 and 7.2
(conf/thesis/published.yaml, 52 cells: every design case of chapter 6 and
the baseline rows of chapter 7); the model is the project's nominal design
(conf/design/baseline.yaml + conf/variant/<case>.yaml) on the same tests as
scripts/thesis_comparison.py; the unknowns are factors on the 'engineering
estimate' and synthetic values listed, with their plausible ranges, in
conf/thesis/inverse.yaml. Steps (scripts/thesis_inverse_core.py):

1. identifiability at the nominal design: forward-difference Jacobian of the
   scaled residuals in log-parameter space, SVD of the range-scaled
   Jacobian, subset selection by pivoted QR;
2. the inverse fit of that subset with the calibration core's Gauss-Newton
   (dampertwin.calibration.optimisers.run, GaussNewtonSettings) inside the
   ranges, in rounds restarted with a fresh Jacobian;
3. identifiability again at the fit; cells before / after.

Writes results/thesis_inverse.json and docs/validation/thesis-inverse.md.
The fitted values are a CANDIDATE baseline: nothing under conf/design,
conf/variant or src changes.

    PYTHONPATH=src nice -n 19 python scripts/thesis_inverse.py   (~15 CPU min, 1 core)
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

import thesis_comparison as tc  # noqa: E402
import thesis_inverse_core as ic  # noqa: E402

CONFIG = ROOT / "conf" / "thesis" / "inverse.yaml"
OUT_MD = ROOT / "docs" / "validation" / "thesis-inverse.md"
OUT_JSON = ROOT / "results" / "thesis_inverse.json"


def log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def fit_mask(cells: list, excluded: list, where: str) -> tuple[np.ndarray, dict]:
    """Cells in the objective (True) and the reason of each excluded one."""
    reasons = {}
    for e in excluded or []:
        label = f"{e['table']}/{e['no']}/{e['column']}"
        if label not in {c.label for c in cells}:
            raise ValueError(f"{where}: excluded cell {label} is not a cell of the published tables")
        reasons[label] = str(e["reason"])
    return np.array([c.label not in reasons for c in cells]), reasons


def counts(cells: list, values) -> dict:
    """Cells within 15 % / 2 dB per table."""
    d = ic.diffs(cells, values)
    out = {}
    for t in ic.TABLE_KEYS:
        ok = [tc.agrees(x, c.unit) for c, x in zip(cells, d) if c.table == t]
        out[t] = [int(sum(ok)), len(ok)]
    return out


def trends(pub: dict, cells: list, values) -> dict:
    """scripts/thesis_comparison.py's current-dependence check on these values."""
    proj = {t: {(c.case, c.column): v for c, v in zip(cells, values) if c.table == t} for t in ic.TABLE_KEYS}
    out = {}
    for t, key in ic.TABLE_KEYS.items():
        cols = tc.HALVES if t in ic.PEAK_TABLES else tc.FREQS
        tab = {**pub[key], "rows": [r for r in pub[key]["rows"] if r["case"].startswith("baseline_")]}
        rows = tc.compare_rows(tab, proj[t], cols, "%" if t in ic.PEAK_TABLES else "dB")
        for c in cols:
            out[f"table {t} {c}"] = tc.current_trend(rows, c)
    return out


def spectrum_dependence(S: np.ndarray, cells: list, params: list) -> list[dict]:
    """dB change of every PSD cell per doubling of each random-test band level (from S)."""
    idx = {p.name: j for j, p in enumerate(params)}
    bands = [p.name for p in params if any(k.startswith("random.") for k in p.keys)]
    out = []
    for i, c in enumerate(cells):
        if c.unit != "dB":
            continue
        row = {"cell": c.label, "case": c.case}
        for b in bands:  # z = (thesis - project) / 2 dB: d project = -2 dB * dz
            row[f"{b} [dB per doubling]"] = float(-c.sigma * S[i, idx[b]] * math.log(2.0))
        out.append(row)
    return out


def fitted_values(sim, params: list, theta: dict) -> list[dict]:
    """Per parameter: its keys' nominal and fitted values [SI]."""
    base = sim._ctx["base"]
    over = ic.case_overrides(base, {}, params, theta)
    coef0 = sim.maps["active_valve_baseline.csv"]
    coef = ic.map_coefficients(coef0, params, theta)
    proto0 = sim._ctx["proto"]["random"]
    proto = ic.random_protocol(proto0, params, theta)
    out = []
    for p in params:
        vals = []
        for k in p.keys:
            if k.startswith("map."):
                n = k.split(".", 1)[1]
                vals.append({"key": k, "nominal": coef0[n], "fitted": coef[n]})
            elif k.startswith("random."):
                i = int(k.split(".")[2])
                vals.append({"key": k, "nominal": proto0["bands"][i]["rms"], "fitted": proto["bands"][i]["rms"]})
            else:
                v0 = base[k]
                vals.append({"key": k, "nominal": list(v0) if isinstance(v0, tuple) else v0,
                             "fitted": over.get(k, list(v0) if isinstance(v0, tuple) else v0)})
        out.append({"parameter": p.name, "values": vals})
    return out


def run_study(pub: dict, doc: dict) -> dict:
    """Identifiability, the fit, identifiability at the fit: everything the outputs hold."""
    t_cpu, t_wall = time.process_time(), time.time()
    params = ic.load_params(doc, str(CONFIG))
    st = doc["fit"]
    sim = ic.Simulator(pub, params, doc["maps"])
    cells = ic.cells_of(pub)
    mask, reasons = fit_mask(cells, doc.get("excluded"), str(CONFIG))

    def f(theta):
        return ic.scaled_residual(cells, sim.values(theta, cells))

    log(f"nominal + Jacobian of {len(params)} parameters on {len(cells)} cells")
    v0 = sim.values({}, cells)
    z0 = ic.scaled_residual(cells, v0)
    _, S0 = ic.jacobian(f, params, {}, float(st["step_log"]), z0)
    id0 = ic.identifiability(S0[mask], params, float(st["identified_sv"]))
    names = list(id0["selected"])
    log(f"rank {id0['rank']}: fitting {names}")
    problem = ic.make_problem(sim, cells, mask)
    theta, start, J_u, rounds = {}, (z0, v0), ic.to_u_columns(S0, params, names), []
    sub = [p for p in params if p.name in names]
    res = None
    for r in range(int(st["rounds"])):
        res = ic.fit(problem, params, names, theta, J_u, start, int(st["iterations"]), 0.05, float(st["tol"]))
        theta = {**theta, **{k: float(v) for k, v in res.best.items()}}
        rounds.append({"round": r + 1, "objective start": float(res.start_objective),
                       "objective": float(res.best_objective), "evaluations": int(res.evaluations),
                       "history": [float(x) for x in res.history["objective"]],
                       "bound_hits": res.bound_hits, "theta": dict(theta)})
        log(f"round {r + 1}: chi2 {res.best_objective:.2f}, theta {theta}")
        v1 = np.asarray(res.simulated, float)
        z1 = ic.scaled_residual(cells, v1)
        if r + 1 < int(st["rounds"]):
            _, S1 = ic.jacobian(f, sub, theta, float(st["step_log"]), z1)
            J_u, start = ic.to_u_columns(S1, sub, names), (z1, v1)
    v1 = np.asarray(res.simulated, float)
    z1 = ic.scaled_residual(cells, v1)
    log("Jacobian at the fit")
    _, S1 = ic.jacobian(f, params, theta, float(st["step_log"]), z1)
    id1 = ic.identifiability(S1[mask], params, float(st["identified_sv"]))
    d0, d1 = ic.diffs(cells, v0), ic.diffs(cells, v1)
    by = {p.name: p for p in params}
    out = {
        "config": str(CONFIG.relative_to(ROOT)), "ranges": doc["ranges"], "settings": st,
        "residual scaling": "z = (thesis - project) / tolerance; tolerance 15 % of |thesis| (peaks) or 2 dB (PSD)",
        "parameters": [{"parameter": p.name, "keys": list(p.keys), "lo": p.lo, "hi": p.hi, "range": p.range,
                        "note": p.note, "offset": p.offset, "scale_variants": p.scale_variants, "start": 1.0,
                        "fitted": float(theta.get(p.name, 1.0)), "in fit": p.name in names,
                        "bound": next((b["bound"] for b in res.bound_hits if b["parameter"] == p.name), None)}
                       for p in params],
        "values": fitted_values(sim, params, theta),
        "identifiability nominal": id0, "identifiability fit": id1,
        "cells": [{"cell": c.label, "table": c.table, "no": c.no, "case": c.case, "column": c.column,
                   "unit": c.unit, "thesis": c.thesis, "before": float(a), "after": float(b), "diff before": x,
                   "diff after": y, "agree before": tc.agrees(x, c.unit), "agree after": tc.agrees(y, c.unit),
                   "in fit": bool(m), "excluded because": reasons.get(c.label)}
                  for c, a, b, x, y, m in zip(cells, v0, v1, d0, d1, mask)],
        "within target before": counts(cells, v0), "within target after": counts(cells, v1),
        "chi2 before": float(np.sum(z0[mask] ** 2)), "chi2 after": float(np.sum(z1[mask] ** 2)),
        "current dependence before": trends(pub, cells, v0), "current dependence after": trends(pub, cells, v1),
        "spectrum dependence before": spectrum_dependence(S0, cells, params),
        "spectrum dependence after": spectrum_dependence(S1, cells, params),
        "rounds": rounds,
        "cost": {"simulation sets": sim.count, "runs per set": 23, "cpu [s]": time.process_time() - t_cpu,
                 "wall [s]": time.time() - t_wall},
        "fitted subset": names, "half log ranges": {p.name: by[p.name].half_log_range for p in params},
        "jacobian nominal": {"rows": [c.label for c in cells], "columns": [p.name for p in params], "S": S0.tolist()},
        "jacobian fit": {"rows": [c.label for c in cells], "columns": [p.name for p in params], "S": S1.tolist()},
    }
    out["provenance"] = tc.provenance()
    return out


def reading(res: dict, pub: dict) -> list[str]:
    """The study's reading, composed from the result."""
    return []


def main(argv: list[str]) -> int:
    """``--from-json``: rewrite the page from the committed JSON (no simulation)."""
    from dampertwin.design import yaml_load_file

    from thesis_inverse_md import markdown

    pub = yaml_load_file(tc.PUBLISHED)
    if "--from-json" in argv:
        res = json.loads(OUT_JSON.read_text())
    else:
        res = json.loads(json.dumps(tc._clean(run_study(pub, yaml_load_file(CONFIG)))))
        tc.atomic_write(OUT_JSON, json.dumps(res, indent=1, sort_keys=True) + "\n")
    tc.atomic_write(OUT_MD, markdown(res, reading(res, pub)))
    log(f"wrote {OUT_MD.relative_to(ROOT)} and {OUT_JSON.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
