"""The approach-1 study report: results/approach1/report.md (+ report.html):
thesis tables 6.5 / 6.6 with flags, every fit's parameters with Gauss-Newton
95 % intervals and identifiability, objective before / after, and the plots
embedded (relative links). Built by the `compare` stage from its own inputs;
``build_report`` needs only the study folder's tables and JSON files."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd

from .calibration.uncertainty import CORR_MAX, REL_CI_MAX

PEAK_FLAG_PCT = 10.0  # |diff| [%] flagged in table 6.5
PSD_FLAG_DB = 3.0     # |diff| [dB] flagged in table 6.6
CASE_PLOTS = ("monosine", "psd")


def _fmt(v, digits: int = 4) -> str:
    if v is None:
        return "-"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_fmt(x, 3) for x in v) + "]"
    if isinstance(v, float):
        if math.isnan(v):
            return "-"
        if not math.isfinite(v):
            return str(v)
        return f"{v:.{digits}g}"
    return str(v)


def _md_table(df: pd.DataFrame) -> str:
    cols = list(df.columns)
    lines = ["| " + " | ".join(map(str, cols)) + " |", "|" + "---|" * len(cols)]
    for _, r in df.iterrows():
        lines.append("| " + " | ".join(_fmt(r[c]) for c in cols) + " |")
    return "\n".join(lines)


def _flag_rows(t: pd.DataFrame, cols: list[str], limit: float, unit: str) -> tuple[pd.DataFrame, list[dict]]:
    """Mark table rows with a cell beyond ``limit``; one flag per row (case)
    listing its cells beyond it."""
    t = t.copy()
    flags = []
    mark = []
    for _, r in t.iterrows():
        bad = [c for c in cols if c in r and abs(float(r[c])) > limit]
        mark.append("**FLAG**" if bad else "")
        if bad:
            where = str(r.get("Design case", r.iloc[1]))
            cur = next((r[c] for c in t.columns if str(c).startswith("Active valve current")), None)
            where += "" if cur is None else f", {float(cur):g} A"
            flags.append({"where": where, "flag": f"abs. diff > {limit:g} {unit}",
                          "detail": ", ".join(f"{c} {float(r[c]):+.2f}" for c in bad)})
    t["flag"] = mark
    return t, flags


def fit_rows(fits: dict) -> tuple[pd.DataFrame, list[dict]]:
    """One row per fitted parameter: value, 95 % interval, relative
    half-width, determined (calibration.uncertainty, via fits.json); and
    the fits' flags (one per fit and kind: failures, no improvement,
    parameters not determined - with what is determined instead)."""
    rows, flags = [], []
    for name, f in fits.get("fits", {}).items():
        unc = (f.get("uncertainty") or {}).get("parameters", {})
        if f.get("failed_simulations"):
            flags.append({"where": name, "flag": "failed simulations",
                          "detail": f"{f['failed_simulations']} during the GA"})
        if f.get("objective_best", 0) >= f.get("objective_start", math.inf):
            flags.append({"where": name, "flag": "objective not lowered", "detail": ""})
        bad = [k for k, u in unc.items() if k in f.get("values", {}) and not u["determined"]]
        if bad:
            det = (f.get("determined") or {}).get("quantity")
            flags.append({"where": name, "flag": f"{len(bad)} of {len(f.get('values', {}))} parameters not determined",
                          "detail": ", ".join(k.split(".")[-1] for k in bad)
                          + (f"; determined: {det.split(' (')[0].split(',')[0]} (below)" if det else "")})
        for key, value in f.get("values", {}).items():
            u = unc.get(key)
            rows.append({"fit": name, "parameter": key, "value": value,
                         "95 % interval": None if u is None else u["ci95"],
                         "rel. half-width [%]": None if u is None else 100 * u["rel_halfwidth"],
                         "determined": "-" if u is None else ("yes" if u["determined"] else f"**no** ({u['why']})")})
    return pd.DataFrame(rows), flags


def determined_tables(fits: dict) -> list[str]:
    """Markdown of what each fit's record determines (valve lift-force
    curves, top-mount dynamic stiffness), with 95 % bands."""
    md = []
    for name, f in fits.get("fits", {}).items():
        det = f.get("determined")
        if not det or "error" in det:
            continue
        if "curve" in det:
            rows = [{"lift [mm]": 1e3 * r["lift [m]"], "force [N]": r["force [N]"],
                     "95 % band [N]": [r["ci95 low [N]"], r["ci95 high [N]"]],
                     "rel. half-width [%]": r["rel. half-width [%]"]} for r in det["curve"]]
        else:
            rows = [{"frequency [Hz]": r["frequency [Hz]"], "|K*| [N/mm]": r["stiffness [N/m]"] / 1e3,
                     "95 % band [N/mm]": [x / 1e3 for x in r["stiffness ci95 [N/m]"]],
                     "loss angle [deg]": r["loss angle [deg]"], "95 % band [deg]": r["loss angle ci95 [deg]"]}
                    for r in det["rows"]]
        md += [f"### {name}: {det['quantity']}", "", _md_table(pd.DataFrame(rows)), ""]
    return md


def build_report(study: str | Path, *, measured_label: str = "", cases: list[str] | None = None) -> tuple[Path, Path]:
    """Write study/report.md and study/report.html from the study folder.
    ``cases``: the case folder names in table order (default: conf/variant)."""
    study = Path(study)
    t65 = pd.read_parquet(study / "table_6_5.parquet")
    t66 = pd.read_parquet(study / "table_6_6.parquet")
    fits = json.loads((study / "fits.json").read_text())
    metrics = json.loads((study / "metrics.json").read_text())
    # the thresholds compare used (conf/compare.yaml, in metrics.json), else the defaults here
    thr = (metrics.get("flags") or {}).get("thresholds", {})
    peak_pct, psd_db = float(thr.get("percent", PEAK_FLAG_PCT)), float(thr.get("dB", PSD_FLAG_DB))
    t65f, flags65 = _flag_rows(t65, [c for c in t65.columns if "diff [%]" in c], peak_pct, "%")
    t66f, flags66 = _flag_rows(t66, [c for c in t66.columns if "diff [dB]" in c], psd_db, "dB")
    fr, fit_flags = fit_rows(fits)
    profile = fits.get("profile", "?")
    md = [f"# Approach-1 study report (profile `{profile}`)", ""]
    if measured_label:
        md += [f"Measurements: {measured_label}.", ""]
    md += ["Thesis chapter 6: valve fits on the flow bench, compliance fit, top-mount fits, then the calibrated "
           "model against the measured mono-sine and random tests. Diff % = (measured - simulated) / measured "
           "x 100; diff dB = simulated - measured. Intervals: linearised 95 % (Student t) from the residual "
           "Jacobian at the polished optimum, corrected for autocorrelated residuals (effective sample size) - "
           "approximate, local, and conditional on the model being right (each fit's uncertainty.md has the "
           "correlations).", ""]
    md += ["## Flags", ""]
    all_flags = flags65 + flags66 + fit_flags
    md += [_md_table(pd.DataFrame(all_flags, columns=["where", "flag", "detail"]))] if all_flags else ["none"]
    md += ["", f"Thresholds: |peak diff| > {peak_pct:g} %, |PSD diff| > {psd_db:g} dB, a parameter is not "
           f"determined when its interval half-width exceeds {REL_CI_MAX:.0%} of its value, it correlates with "
           f"another beyond |{CORR_MAX}|, or it loads a singular direction of the Jacobian.", ""]
    md += ["## Summary metrics", "", _md_table(pd.DataFrame(
        [{"metric": k, "mean abs diff": v["mean_abs"], "max abs diff": v["max_abs"]} for k, v in metrics.items()
         if isinstance(v, dict) and "mean_abs" in v])), ""]
    md += ["## Table 6.5 - mono-sine rod acceleration peaks [g]", "", _md_table(t65f), ""]
    md += ["## Table 6.6 - random-test rod acceleration PSD [dB re 1 g^2/Hz]", "", _md_table(t66f), ""]
    md += ["## Fitted parameters", ""]
    obj = pd.DataFrame([{"fit": n, "objective before": f["objective_start"], "objective after": f["objective_best"],
                         "improvement [%]": 100 * (1 - f["objective_best"] / f["objective_start"])
                         if f["objective_start"] else None, "evaluations": f["evaluations"],
                         "failed": f["failed_simulations"]} for n, f in fits.get("fits", {}).items()])
    if len(obj):
        md += [_md_table(obj), ""]
    det = determined_tables(fits)
    if det:
        md += ["## What the data determine", "",
               "Where coefficients trade off (pairwise |corr| near 1, intervals wider than the values), the "
               "record still fixes the curve they draw: each valve's spring force over the lift range the test "
               "reached (eq. 4.19), the top mount's dynamic stiffness and loss angle at the sweep frequencies. "
               "Bands: the fit's covariance propagated to the quantity (delta method; unresolved directions at "
               "the Jacobian's resolution limit), 95 %, Student t.", ""] + det
    if len(fr):
        if fr["95 % interval"].isna().all():
            md += ["(no intervals recorded for these fits: rerun the fit stages to compute them)", ""]
        md += [_md_table(fr), ""]
    md += ["## Plots", "", "### Fits", ""]
    for name in fits.get("fits", {}):
        for png in ("pq.png", "compliance.png", "topmount.png"):
            if (name.startswith("valves/") and png == "pq.png") or (name == "compliance" and png == "compliance.png") \
                    or (name.startswith("topmount/") and png == "topmount.png"):
                md += [f"![{name}]({name}/{png})", ""]
    md += ["### Design cases", "",
           "Mono-sine plots shade the KPI window (the last cycle) and mark the chosen rebound / compression peaks.",
           ""]
    case_col = "Design case" if "Design case" in t65.columns else t65.columns[1]
    cases = _case_folders(study) if cases is None else cases
    for title, folder in zip(t65[case_col], cases):
        md += [f"#### {title}", ""]
        md += [f"![{folder} {p}](plots/{folder}/{p}.png)" for p in CASE_PLOTS]
        if folder == "baseline_1.6":
            md += [f"![{folder} curving](plots/{folder}/curving.png)"]
        md += [""]
    text = "\n".join(md) + "\n"
    md_path = study / "report.md"
    _write(md_path, text)
    html_path = study / "report.html"
    _write(html_path, to_html(text, f"Approach-1 study report ({profile})"))
    return md_path, html_path


def _case_folders(study: Path) -> list[str]:
    """Case folder names in table order (table rows follow conf/variant order = the 'no.' column)."""
    from .variants import load_variants
    from .config import repo_root

    try:
        return [v.case for v in load_variants(repo_root(study) / "conf" / "variant")]
    except FileNotFoundError:
        return []


def to_html(markdown_text: str, title: str) -> str:
    """Markdown -> a standalone HTML page (markdown-it-py, tables enabled)."""
    from markdown_it import MarkdownIt

    body = MarkdownIt("commonmark").enable("table").render(markdown_text)
    style = ("body{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em}"
             "table{border-collapse:collapse;font-size:0.85em}td,th{border:1px solid #ccc;padding:2px 6px}"
             "img{max-width:100%}")
    return f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>{title}</title><style>{style}</style>" \
           f"</head><body>\n{body}</body></html>\n"


def _write(path: Path, text: str) -> None:
    import os

    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)


__all__ = ["build_report", "to_html", "fit_rows", "PEAK_FLAG_PCT", "PSD_FLAG_DB"]
