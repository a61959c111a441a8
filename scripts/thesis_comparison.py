"""The thesis' own-model numbers beside the project's NOMINAL model (issue 40,
acceptance item 1).

Reads the hand transcription conf/thesis/published.yaml (tables 4.1, 6.1,
6.4, 6.5, 6.6, 7.1, 7.2, the calibrated values of 6.3.2, the valve-event
times named in the text of fig. 6.20), simulates the nominal design
(conf/design/baseline.yaml + the case's conf/variant/<case>.yaml) through
the standard tests (conf/test/<test>.yaml, runs built by
dampertwin.protocols.build_runs with the study's seed) and the project's
KPIs (dampertwin.kpi), and writes

    docs/validation/thesis-comparison.md   (tables and a short reading)
    results/thesis_comparison.json         (machine-readable, same numbers)

Difference convention used HERE (stated in both outputs):
    diff [%]  = (project - thesis) / |thesis| * 100   (peaks, velocities)
    diff [dB] = project - thesis                     (PSD levels)
with the thesis' SIMULATED value as the reference. A positive % on a
compression peak (both negative) means the project's peak is smaller in
magnitude. The thesis' own Diff. columns use other conventions (see
``thesis_rule``; they differ between its tables).

    PYTHONPATH=src python scripts/thesis_comparison.py        (~1 min, 1 core)
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PUBLISHED = ROOT / "conf" / "thesis" / "published.yaml"
OUT_MD = ROOT / "docs" / "validation" / "thesis-comparison.md"
OUT_JSON = ROOT / "results" / "thesis_comparison.json"
PCT_AGREE = 15.0  # [%] issue 40 acceptance 3: peaks within 15 %
DB_AGREE = 2.0  # [dB] issue 40 acceptance 3: PSD within 2 dB
HALVES = ("rebound", "compression")
FREQS = ("f200", "f300")
VALVES = ("piston_rebound", "piston_intake", "base_compression", "base_intake")
LIFT_OPEN = 1e-6  # [m] a valve counts as open above this lift (event times of fig. 6.20)


# ------------------------------------------------------------------ arithmetic (pure)
def pct_diff(project: float, thesis: float) -> float:
    """(project - thesis) / |thesis| * 100 [%]; the thesis' value is the base."""
    return (project - thesis) / abs(thesis) * 100.0


def db_diff(project: float, thesis: float) -> float:
    """project - thesis [dB]."""
    return project - thesis


def agrees(diff: float, unit: str) -> bool:
    """Within 15 % (unit '%') or 2 dB (unit 'dB') of the thesis."""
    limit = {"%": PCT_AGREE, "dB": DB_AGREE}[unit]
    return bool(abs(diff) <= limit)


def thesis_rule(rule: str, s: float, m: float) -> float:
    """The thesis' own Diff. column from its simulated s and measured m."""
    if rule == "pct_signed_m":
        return (m - s) / m * 100.0
    if rule == "pct_abs_m":
        return (m - s) / abs(m) * 100.0
    if rule == "db_abs":
        return abs(s - m)
    raise ValueError(f"unknown diff_rule {rule!r}; expected pct_signed_m, pct_abs_m or db_abs")


def rule_interval(rule: str, s: float, m: float, r: float) -> tuple[float, float]:
    """Range of ``thesis_rule`` over s, m each within +-r (the printed
    rounding); each rule is monotonic in s and m on the box unless m crosses 0
    (refused) or s - m crosses 0 (db_abs: the minimum is 0)."""
    if abs(m) <= r:
        raise ValueError(f"measured {m} within the rounding {r} of zero: percentage undefined")
    vals = [thesis_rule(rule, s + a, m + b) for a in (-r, r) for b in (-r, r)]
    lo, hi = min(vals), max(vals)
    if rule == "db_abs" and abs(s - m) <= 2 * r:
        lo = 0.0
    return lo, hi


def check_thesis_arithmetic(pub: dict) -> list[dict]:
    """Every Diff. cell of tables 6.5 / 6.6 / 7.1 / 7.2 recomputed from the
    printed s / m under the table's rule, with the rounding range; a cell is
    consistent when the printed diff (itself rounded to 0.05) lies in it."""
    r = float(pub["rounding"])
    out = []
    for key, cols in (("table_6_5", HALVES), ("table_6_6", FREQS), ("table_7_1", HALVES), ("table_7_2", FREQS)):
        tab = pub[key]
        for row in tab["rows"]:
            for c in cols:
                cell = row[c]
                lo, hi = rule_interval(tab["diff_rule"], cell["s"], cell["m"], r)
                out.append({"table": tab["ref"]["table"], "no": row["no"], "column": c, "rule": tab["diff_rule"],
                            "printed": cell["diff"], "recomputed": thesis_rule(tab["diff_rule"], cell["s"], cell["m"]),
                            "range": [lo, hi], "consistent": bool(lo - r <= cell["diff"] <= hi + r)})
    return out


def compare_rows(tab: dict, project: dict, cols: tuple, unit: str) -> list[dict]:
    """Rows of thesis-simulated vs project values: ``project[(case, col)]``."""
    fn = pct_diff if unit == "%" else db_diff
    rows = []
    for row in tab["rows"]:
        out = {"no": row["no"], "case": row["case"], "current": row["current"]}
        for c in cols:
            t, p = row[c]["s"], project[(row["case"], c)]
            d = fn(p, t)
            out[c] = {"thesis": t, "project": p, "diff": d, "agree": agrees(d, unit)}
        rows.append(out)
    return rows


def current_trend(rows: list[dict], col: str) -> dict:
    """Baseline rows only: the value at 1.6 / 0.9 / 0.32 A, thesis and
    project, and the change 1.6 A -> 0.32 A of each (same sign and within a
    factor 2 of each other counts as 'reproduced')."""
    by = {r["current"]: r[col] for r in rows if r["case"].startswith("baseline_")}
    cur = sorted(by, reverse=True)
    t = [by[c]["thesis"] for c in cur]
    p = [by[c]["project"] for c in cur]
    dt, dp = t[-1] - t[0], p[-1] - p[0]
    ok = bool(dt != 0 and dp * dt > 0 and 0.5 <= dp / dt <= 2.0)
    return {"currents": cur, "thesis": t, "project": p, "thesis_change": dt, "project_change": dp, "reproduced": ok}


# ------------------------------------------------------------------ event times (pure)
def crossings(t: np.ndarray, lift: np.ndarray, level: float) -> tuple[np.ndarray, np.ndarray]:
    """Times [s] a lift signal rises above / falls below ``level``."""
    above = lift > level
    k = np.flatnonzero(np.diff(above.astype(int)))
    ups = t[k + 1][above[k + 1]]
    downs = t[k + 1][~above[k + 1]]
    return ups, downs


def next_after(a: np.ndarray, b: np.ndarray, t_from: float) -> float:
    """Delay [s] from the first event of ``a`` at or after ``t_from`` to the
    next event of ``b`` (nan when either is missing)."""
    a = a[a >= t_from]
    if not len(a):
        return float("nan")
    b = b[b > a[0]]
    return float(b[0] - a[0]) if len(b) else float("nan")


# ------------------------------------------------------------------ simulation (script layer)
def _sim_runs():
    """Closure running the nominal design per (case, test); cached."""
    from dampertwin.design import load, yaml_load_file
    from dampertwin.protocols import build_runs, load_protocol
    from dampertwin.variants import load_variant

    base = load(ROOT / "conf" / "design" / "baseline.yaml")
    seed = int(yaml_load_file(ROOT / "conf" / "config.yaml")["seed"])
    cache: dict = {}

    def frames(case: str, test: str):
        if (case, test) in cache:
            return cache[(case, test)]
        v = load_variant(ROOT / "conf" / "variant" / f"{case}.yaml")
        d = v.apply(base)
        proto = load_protocol(ROOT / "conf" / "test" / f"{test}.yaml")
        runs = build_runs(proto, seed)
        if proto["protocol"] in ("monosine", "random"):
            runs = [r for r in runs if abs(r.current - v.current) < 1e-9]
        cache[(case, test)] = (d, proto, simulate_runs(d, runs, f"{case}/{test}"))
        return cache[(case, test)]

    return frames


def simulate_runs(d, runs, label: str) -> list:
    """[(run, its simulated frame)] of design ``d`` for each run; a failed
    simulation raises, naming ``label`` and the run."""
    from dampertwin.simulation import simulate

    out = []
    for r in runs:
        res = simulate(d, r.excitation, r.configuration, current=r.current, rate=r.rate)
        if not res.ok:
            raise RuntimeError(f"{label}/{r.name}: simulation failed: {res.stats.message}")
        out.append((r, res.to_frame()))
    return out


def project_values(pub: dict, frames) -> dict:
    """The project's nominal KPIs for every cell of the transcription."""
    from dampertwin import kpi
    from dampertwin.design import yaml_load_file

    n_tr = int(yaml_load_file(ROOT / "conf" / "compare.yaml")["transient_cycles"])
    vals: dict = {"6.5": {}, "6.5x": {}, "6.6": {}, "7.1": {}, "7.1x": {}}
    for key, tag, test in (("table_6_5", "6.5", "monosine"), ("table_7_1", "7.1", "monosine16")):
        for row in pub[key]["rows"]:
            _, proto, [(run, df)] = frames(row["case"], test)
            lit = kpi.rod_acceleration_peaks(df, proto["frequency"])
            ext = kpi.rod_acceleration_extremes(df, proto["frequency"], n_tr)
            for h in HALVES:
                vals[tag][(row["case"], h)] = lit[h]
            vals[tag + "x"][(row["case"], "rebound")] = ext["rebound max"]
            vals[tag + "x"][(row["case"], "compression")] = ext["compression min"]
    for row in pub["table_6_6"]["rows"]:
        _, _, [(run, df)] = frames(row["case"], "random")
        lv = kpi.psd_levels(df)
        vals["6.6"][(row["case"], "f200")] = lv["200 Hz [dB]"]
        vals["6.6"][(row["case"], "f300")] = lv["300 Hz [dB]"]
        vals["psd"] = {"resolution [Hz]": lv["resolution [Hz]"], "band [Hz]": lv["band [Hz]"]}
    return vals


def valve_velocities(frames) -> dict:
    """Table 4.1 counterpart: max opening velocity [mm/s] of each valve over
    the damper-level compliance test (all its runs; the thesis does not name
    its test), from the lift channels."""
    _, _, runs = frames("baseline_1.6", "compliance")
    out = {}
    for v in VALVES:
        vmax = 0.0
        for _, df in runs:
            t, x = df["time [s]"].to_numpy(), df[f"lift {v} [m]"].to_numpy()
            vmax = max(vmax, float(np.max(np.gradient(x, t))))
        out[v] = vmax * 1e3
    return out


def event_delays(pub: dict, frames) -> list[dict]:
    """Fig. 6.20 counterpart: delays between the valve events the text names,
    thesis (differences of its printed times) vs the nominal 13 Hz / 1.6 A
    mono-sine (last two cycles)."""
    _, proto, [(run, df)] = frames("baseline_1.6", "monosine")
    t = df["time [s]"].to_numpy()
    ev = {}
    for v in ("piston_intake", "base_intake", "piston_rebound"):
        ups, downs = crossings(t, df[f"lift {v} [m]"].to_numpy(), LIFT_OPEN)
        ev[f"{v}_opening"], ev[f"{v}_closing"] = ups, downs
    t_from = t[-1] - 2.0 / proto["frequency"]
    pt = {e["event"]: e["t"] for e in pub["fig_6_20_events"]["events"]}
    pairs = [("piston_intake_closing", "base_intake_opening"), ("base_intake_opening", "piston_rebound_closing"),
             ("piston_rebound_closing", "piston_intake_opening"), ("base_intake_opening", "piston_intake_opening")]
    out = []
    for a, b in pairs:
        th = pt[b] - pt[a]
        pr = next_after(ev[a], ev[b], t_from)
        out.append({"from": a, "to": b, "thesis [ms]": th * 1e3, "project [ms]": pr * 1e3,
                    "diff [%]": pct_diff(pr, th) if math.isfinite(pr) else float("nan")})
    return out


def parameter_values(pub: dict) -> dict:
    """Published values (6.3.2 text, stated values) and the GA limits of
    tables 6.1 / 6.4 beside the baseline design's values."""
    from dampertwin.design import yaml_load_file

    doc = yaml_load_file(ROOT / "conf" / "design" / "baseline.yaml")
    par = {(p.get("group"), p["name"]): p for p in doc["parameters"]}
    par.update({("constants", c["name"]): c for c in doc["constants"]})

    def value(key: str):
        if "/" in key:  # <variant>/<group.name>
            case, k = key.split("/")
            return yaml_load_file(ROOT / "conf" / "variant" / f"{case}.yaml")["overrides"][k], "variant " + case
        g, n = key.split(".")
        p = par[(g, n)]
        return p["value"], str(p.get("source", ""))

    calibrated = []
    for c in pub["calibrated"] + pub["stated"]:
        v, src = value(c["key"])
        row = {"key": c["key"], "printed": c["printed"], "unit": c["unit"], "ref": c["ref"], "baseline": v,
               "baseline_source": src}
        if "value" in c:
            row.update(thesis=c["value"], diff=pct_diff(float(v), float(c["value"])))
        else:
            row.update(thesis=[c["low"], c["high"]], inside=bool(c["low"] <= float(v) <= c["high"]))
        calibrated.append(row)
    limits = []
    for r in pub["limits_6_1"]["rows"]:
        groups = ["constants"] if r["name"].startswith("constants.") else pub["limits_6_1"]["groups"]
        name = r["name"].split(".")[-1]
        for g in groups:
            if (g, name) in par:
                limits.append(_limit_row("6.1", r, g, name, par[(g, name)]["value"]))
    for r in pub["limits_6_4"]["rows"]:
        limits.append(_limit_row("6.4", r, "top_mount", r["name"], par[("top_mount", r["name"])]["value"]))
    published = [{"key": f"{g}.{n}" if g else n, "value": p["value"], "source": str(p.get("source", ""))}
                 for (g, n), p in par.items()
                 if not str(p.get("source", "")).startswith("engineering estimate")
                 and ("thesis " in str(p.get("source", "")) or "table 5.1" in str(p.get("source", "")))]
    return {"calibrated": calibrated, "limits": limits, "published_sources": published}


def _limit_row(table, r, group, name, value) -> dict:
    lo, hi = r["low"] * r["si"], r["high"] * r["si"]
    return {"table": table, "printed": r["printed"], "key": f"{group}.{name}", "low_si": lo, "high_si": hi,
            "baseline": value, "inside": bool(lo <= float(value) <= hi)}


# ------------------------------------------------------------------ outputs
def atomic_write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(tmp, path)


def build(pub: dict, frames) -> dict:
    """Everything the two outputs hold."""
    v = project_values(pub, frames)
    res = {"convention": {"percent": "(project - thesis) / |thesis| * 100, thesis simulated value as base",
                          "dB": "project - thesis", "agree": {"percent": PCT_AGREE, "dB": DB_AGREE}},
           "model": "nominal design conf/design/baseline.yaml + conf/variant/<case>.yaml overrides, raw model "
                    "signals (no transducer filter), runs of conf/test/<test>.yaml built with conf/config.yaml seed",
           "kpi": {"peaks": "dampertwin.kpi.rod_acceleration_peaks (thesis literal, THESIS-ERRATA 38)",
                   "peaks_extremes": "dampertwin.kpi.rod_acceleration_extremes (rebound max, compression min)",
                   "psd": "dampertwin.kpi.psd_levels " + json.dumps(v["psd"], sort_keys=True)}}
    res["table_6_5"] = compare_rows(pub["table_6_5"], v["6.5"], HALVES, "%")
    res["table_6_5_extremes"] = compare_rows(pub["table_6_5"], v["6.5x"], HALVES, "%")
    res["table_6_6"] = compare_rows(pub["table_6_6"], v["6.6"], FREQS, "dB")
    res["table_7_1"] = compare_rows(pub["table_7_1"], v["7.1"], HALVES, "%")
    res["table_7_1_extremes"] = compare_rows(pub["table_7_1"], v["7.1x"], HALVES, "%")
    res["table_7_2"] = compare_rows(pub["table_7_2"], v["6.6"], FREQS, "dB")  # same nominal random runs
    res["current_dependence"] = {f"{k} {c}": current_trend(res[k], c) for k, cols in
                                 (("table_6_5", HALVES), ("table_6_6", FREQS), ("table_7_1", HALVES),
                                  ("table_7_2", FREQS)) for c in cols}
    vel = valve_velocities(frames)
    res["table_4_1"] = [{"valve": r["valve"], "thesis": r["s"], "project": vel[r["valve"]],
                         "diff": pct_diff(vel[r["valve"]], r["s"])} for r in pub["table_4_1"]["rows"]]
    res["fig_6_20_delays"] = event_delays(pub, frames)
    res["parameters"] = parameter_values(pub)
    res["thesis_arithmetic"] = check_thesis_arithmetic(pub)
    res["provenance"] = provenance()
    return res


def provenance() -> dict:
    """Package version and the hashes of the nominal design and the transcription."""
    import hashlib

    from dampertwin import __version__
    from dampertwin.design import load

    return {"dampertwin": __version__, "baseline_design_hash": load(ROOT / "conf" / "design" / "baseline.yaml").hash(),
            "published_yaml_sha256": hashlib.sha256(PUBLISHED.read_bytes()).hexdigest()}


def main() -> int:
    from dampertwin.design import yaml_load_file

    sys.path.insert(0, str(ROOT / "scripts"))
    from thesis_comparison_md import markdown

    pub = yaml_load_file(PUBLISHED)
    res = build(pub, _sim_runs())
    atomic_write(OUT_JSON, json.dumps(_clean(res), indent=1, sort_keys=True) + "\n")
    atomic_write(OUT_MD, markdown(res, pub))
    print(f"wrote {OUT_MD.relative_to(ROOT)} and {OUT_JSON.relative_to(ROOT)}")
    return 0


def _clean(x):
    """JSON-safe: NaN -> None, tuples -> lists, numpy -> float."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return None if not math.isfinite(float(x)) else round(float(x), 6)
    return x


if __name__ == "__main__":
    sys.exit(main())
