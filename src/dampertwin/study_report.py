"""The approach-1 study report: results/approach1/report.md (+ report.html):
thesis tables 6.5 / 6.6 with flags, every fit's parameters with their
95 % intervals and identifiability, objective before / after, and the plots
(relative links in the Markdown; embedded as base64 data URIs in the HTML, so
report.html opens offline and without the DVC cache). Also the KPI scatter
data for `dvc plots` (plots/kpi_*.csv) and a static plots page
(plots/index.html, matplotlib PNGs embedded, no network). Built by the
`compare` stage; ``build_report`` needs only the study folder's tables and
JSON files (a PNG absent from the folder is named in the page, not broken)."""

from __future__ import annotations

import base64
import html as html_lib
import json
import math
import re
from pathlib import Path

import pandas as pd

from .calibration.uncertainty import CORR_MAX, REL_CI_MAX
from .io import json_number as _x

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
        lines.append("| " + " | ".join(_fmt(r[c]).replace("|", "\\|") for c in cols) + " |")  # a cell's | is text
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
            worst = max(bad, key=lambda c: abs(float(r[c])))
            flags.append({"where": where, "flag": f"abs. diff > {limit:g} {unit}",
                          "detail": ", ".join(f"{c} {float(r[c]):+.2f}" for c in bad),
                          "worst": f"{where}, {worst} {float(r[worst]):+.2f}", "worst_abs": abs(float(r[worst]))})
    t["flag"] = mark
    return t, flags


def _band(b) -> list[float]:
    """A 95 % interval [low, high] read from standard JSON: a null end is unbounded."""
    return [_x(b[0], -math.inf), _x(b[1], math.inf)]


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
        if _x(f.get("objective_best", 0)) >= _x(f.get("objective_start", math.inf)):  # nan: no flag
            flags.append({"where": name, "flag": "objective not lowered", "detail": ""})
        hits = f.get("bound_hits") or []
        if hits:
            flags.append({"where": name, "flag": "ends on a search bound",
                          "detail": "; ".join(f"{h['parameter'].split('.')[-1]} = {h['value']:.4g} at its {h['bound']} "
                                              f"bound {h['limit']:.4g}" for h in hits)
                          + ": the optimum may lie beyond it, or the parameter stands in for a missing effect"})
        bad = [k for k, u in unc.items() if k in f.get("values", {}) and not u["determined"]]
        if bad:
            det = (f.get("determined") or {}).get("quantity")
            flags.append({"where": name, "flag": f"{len(bad)} of {len(f.get('values', {}))} parameters not determined",
                          "detail": ", ".join(k.split(".")[-1] for k in bad)
                          + (f"; determined: {det.split(' (')[0].split(',')[0]} (below)" if det else ""),
                          "undetermined": [k.split(".")[-1] for k in bad],
                          "determined": det.split(" (")[0].split(",")[0] if det else None})
        for key, value in f.get("values", {}).items():
            u = unc.get(key)
            rows.append({"fit": name, "parameter": key, "value": value,
                         "95 % interval": None if u is None else _band(u["ci95"]),
                         "rel. half-width [%]": None if u is None else 100 * _x(u["rel_halfwidth"], math.inf),
                         "determined": "-" if u is None else ("yes" if u["determined"] else f"**no** ({u['why']})")})
    return pd.DataFrame(rows), flags


def short_flags(kpi_flags: dict[str, tuple[list[dict], int]], fit_flags: list[dict]) -> list[dict]:
    """The report's flags as a short table: one row per KPI table (cases
    beyond the threshold, the worst cell), one per fit family for the
    parameters its records cannot determine (what they determine instead),
    and one per fit for what needs a look (failures, no improvement, a value
    on a search bound). ``kpi_flags``: table name -> (its row flags, rows)."""
    out = []
    for table, (flags, n) in kpi_flags.items():
        if flags:
            w = max(flags, key=lambda f: f["worst_abs"])
            out.append({"where": table, "flag": f"{len(flags)} of {n} cases {flags[0]['flag']}",
                        "detail": f"worst: {w['worst']}; the rows are marked in the table"})
    families: dict[str, list[dict]] = {}
    for f in fit_flags:
        if "undetermined" in f:
            families.setdefault(f["where"].split("/")[0], []).append(f)
        else:
            out.append({k: f[k] for k in ("where", "flag", "detail")})
    for fam, fl in families.items():
        count: dict[str, int] = {}
        for f in fl:
            for k in f["undetermined"]:
                count[k] = count.get(k, 0) + 1
        by_n: dict[int, list[str]] = {}
        for k, c in count.items():
            by_n.setdefault(c, []).append(k)
        dets = sorted({f["determined"] for f in fl if f["determined"]})
        out.append({"where": f"{fam} ({len(fl)} fit{'s' * (len(fl) > 1)})", "flag": "parameters not determined",
                    "detail": "; ".join(f"{', '.join(ks)} in {c}" for c, ks in sorted(by_n.items(), reverse=True))
                    + (f"; determined instead: {', '.join(dets)} (below)" if dets else "")})
    return out


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
                     "95 % band [N]": _band([r["ci95 low [N]"], r["ci95 high [N]"]]),
                     "rel. half-width [%]": _x(r["rel. half-width [%]"], math.inf)} for r in det["curve"]]
        else:
            rows = [{"frequency [Hz]": r["frequency [Hz]"], "|K*| [N/mm]": r["stiffness [N/m]"] / 1e3,
                     "95 % band [N/mm]": [x / 1e3 for x in _band(r["stiffness ci95 [N/m]"])],
                     "loss angle [deg]": r["loss angle [deg]"], "95 % band [deg]": _band(r["loss angle ci95 [deg]"])}
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
    all_flags = short_flags({"table 6.5": (flags65, len(t65)), "table 6.6": (flags66, len(t66))}, fit_flags)
    md += [_md_table(pd.DataFrame(all_flags, columns=["where", "flag", "detail"]))] if all_flags else ["none"]
    md += ["", f"Thresholds: |peak diff| > {peak_pct:g} %, |PSD diff| > {psd_db:g} dB, a parameter is not "
           f"determined when its interval half-width exceeds {REL_CI_MAX:.0%} of its value, it correlates with "
           f"another beyond |{CORR_MAX}|, or it loads a singular direction of the Jacobian.", ""]
    md += ["## Summary metrics", "", _md_table(pd.DataFrame(
        [{"metric": k, "mean abs diff": _x(v["mean_abs"]), "max abs diff": _x(v["max_abs"])} for k, v in metrics.items()
         if isinstance(v, dict) and "mean_abs" in v])), ""]
    md += ["## Table 6.5 - mono-sine rod acceleration peaks [g]", "", _md_table(t65f), ""]
    md += ["## Table 6.6 - random-test rod acceleration PSD [dB re 1 g^2/Hz]", "", _md_table(t66f), ""]
    md += ["## Fitted parameters", ""]
    obj = pd.DataFrame([{"fit": n, "objective before": _x(f["objective_start"]),
                         "objective after": _x(f["objective_best"]),
                         "improvement [%]": 100 * (1 - _x(f["objective_best"]) / _x(f["objective_start"]))
                         if _x(f["objective_start"]) else None, "evaluations": f["evaluations"],
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
    _write(html_path, embed_images(to_html(text, f"Approach-1 study report ({profile})"), study))
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
             "img{max-width:100%}.missing{color:#a00;font-style:italic}")
    return f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>{title}</title><style>{style}</style>" \
           f"</head><body>\n{body}</body></html>\n"


_IMG = re.compile(r'<img src="([^"]+)" alt="([^"]*)"\s*/?>')


def embed_images(page: str, base: Path) -> str:
    """Every ``<img src="relative.png">`` of ``page`` as a base64 data URI
    (the file read from ``base``); an absent file becomes a visible note
    naming it instead of a broken image."""

    def sub(m: re.Match) -> str:
        src, alt = html_lib.unescape(m.group(1)), m.group(2)
        if src.startswith(("data:", "http:", "https:")):
            return m.group(0)
        p = base / src
        if not p.is_file():
            return (f'<span class="missing">[image not available: {html_lib.escape(src)} - a DVC output; '
                    f'<code>dvc repro compare</code> or <code>dvc pull</code> makes it]</span>')
        data = base64.b64encode(p.read_bytes()).decode()
        return f'<img src="data:image/png;base64,{data}" alt="{alt}">'

    return _IMG.sub(sub, page)


KPI_FAMILIES = {"kpi_peaks.csv": tuple(f"{h} {e} [g]" for h in ("rebound", "compression") for e in ("max", "min")),
                "kpi_psd.csv": ("PSD 200 Hz [dB]", "PSD 300 Hz [dB]")}


def kpi_points(t65: pd.DataFrame, t66: pd.DataFrame, cases: list[str]) -> pd.DataFrame:
    """Simulated vs measured per design case and KPI (tables 6.5 / 6.6 in
    long form): columns case, kpi, simulated, measured. ``cases``: the case
    folder names in table row order."""
    if len(cases) != len(t65) or len(cases) != len(t66):
        raise ValueError(f"kpi_points: {len(cases)} cases for tables of {len(t65)} / {len(t66)} rows")
    rows = []
    for case, (_, r65), (_, r66) in zip(cases, t65.iterrows(), t66.iterrows()):
        for h in ("Rebound", "Compression"):
            for e in ("max", "min"):
                rows.append({"case": case, "kpi": f"{h.lower()} {e} [g]", "simulated": float(r65[f"{h} {e} simulated [g]"]),
                             "measured": float(r65[f"{h} {e} measured [g]"])})
        for f in (200, 300):
            rows.append({"case": case, "kpi": f"PSD {f} Hz [dB]", "simulated": float(r66[f"{f} Hz simulated [dB]"]),
                         "measured": float(r66[f"{f} Hz measured [dB]"])})
    return pd.DataFrame(rows)


def write_kpi_plots(study: str | Path, points: pd.DataFrame) -> list[Path]:
    """plots/kpi_peaks.csv, plots/kpi_psd.csv (for `dvc plots show`) and
    plots/kpi_scatter.png (the same, static); a family without rows is an error."""
    plots = Path(study) / "plots"
    plots.mkdir(parents=True, exist_ok=True)
    written = []
    for name, kpis in KPI_FAMILIES.items():
        sel = points[points.kpi.isin(kpis)]
        if sel.empty:
            raise ValueError(f"{plots / name}: no rows for {', '.join(kpis)}; the KPI names changed?")
        _write(plots / name, sel.to_csv(index=False, lineterminator="\n"))
        written.append(plots / name)
    fig = kpi_scatter_figure(points)
    png = plots / "kpi_scatter.png"
    tmp = png.with_name(f".{png.name}.tmp.png")
    fig.savefig(tmp, dpi=100, metadata={"Software": None})
    import os

    import matplotlib.pyplot as plt

    plt.close(fig)
    os.replace(tmp, png)
    return [*written, png]


def kpi_scatter_figure(points: pd.DataFrame):
    """Simulated vs measured, one panel per KPI family, with the y = x line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 5), constrained_layout=True)
    for ax, (name, kpis), title in zip(axes, KPI_FAMILIES.items(),
                                       ("Mono-sine rod acceleration extremes [g] (table 6.5)",
                                        "Random-test PSD [dB re 1 g^2/Hz] (table 6.6)")):
        sel = points[points.kpi.isin(kpis)]
        for k, g in sel.groupby("kpi", sort=False):
            ax.plot(g.measured, g.simulated, "o", ms=5, alpha=0.8, label=k)
        lo = float(min(sel.measured.min(), sel.simulated.min()))
        hi = float(max(sel.measured.max(), sel.simulated.max()))
        pad = 0.05 * (hi - lo or 1.0)
        ax.plot([lo - pad, hi + pad], [lo - pad, hi + pad], "-", color="0.5", lw=1, label="y = x")
        ax.set(xlabel="measured", ylabel="simulated")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("Calibrated model vs measurement, every design case", fontsize=11)
    return fig


def plots_page(study: str | Path) -> Path:
    """plots/index.html: every PNG of the study (KPI scatter, per case, per fit)
    embedded, so it opens offline; written atomically."""
    study = Path(study)
    pngs = sorted(p.relative_to(study).as_posix() for p in study.rglob("*.png") if "checkpoints" not in p.parts)
    first = [p for p in pngs if p == "plots/kpi_scatter.png"]
    md = ["# Approach-1 study: plots", "",
          "Static page: every image is embedded; the `dvc plots show` page needs the Vega scripts from the web.",
          ""]
    md += [f"## {p}\n\n![{p}]({p})\n" for p in first + [p for p in pngs if p not in first]]
    out = study / "plots" / "index.html"
    out.parent.mkdir(parents=True, exist_ok=True)
    _write(out, embed_images(to_html("\n".join(md) + "\n", "Approach-1 study plots"), study))
    return out


def _write(path: Path, text: str) -> None:
    import os

    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)


__all__ = ["build_report", "to_html", "fit_rows", "embed_images", "kpi_points", "write_kpi_plots", "plots_page",
           "KPI_FAMILIES", "PEAK_FLAG_PCT", "PSD_FLAG_DB"]
