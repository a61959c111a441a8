"""OUT/report.md and OUT/plots/*.png of the discrepancy workflow: verdict,
held-out gap before / after, the localised residual map (heat maps record x
phase / band), candidates, the thesis tables (6.5 / 6.6 layouts) before and
after, overlays. Called by ``entry`` only (it owns the output folder)."""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from .. import kpi  # noqa: E402
from . import features as F  # noqa: E402


def _fmt(v, d=3):
    if v is None:
        return "-"
    if isinstance(v, float):
        return "-" if not math.isfinite(v) else f"{v:.{d}g}"
    return str(v)


def _md_table(rows: list[dict]) -> str:
    if not rows:
        return "(none)\n"
    cols = list(rows[0])
    out = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
    out += ["| " + " | ".join(_fmt(r[c]) for c in cols) + " |" for r in rows]
    return "\n".join(out) + "\n"


def _unit_map(problem, z: np.ndarray):
    """Per unit: max |residual / noise| over channels per phase bin / band."""
    rows, i = [], 0
    for u in problem.units:
        n = len(u.labels)
        zz = np.abs(z[i:i + n])
        cols: dict[str, float] = {}
        for (ch, ph), v in zip(u.labels, zz):
            cols[ph] = max(cols.get(ph, 0.0), float(v))
        rows.append((u, cols))
        i += n
    return rows


def heatmaps(problem, z_before, z_after, out) -> list:
    paths = []
    def kind_of(u):
        return "flowbench" if u.drive == F.FLOW else u.kind

    for kind, title in (("sine", "phase bin (stroke position x direction)"),
                        ("flowbench", "flow bin (flow level x ramp direction)"), ("psd", "frequency band")):
        mb = [(u, c) for u, c in _unit_map(problem, z_before) if kind_of(u) == kind]
        ma = [(u, c) for u, c in _unit_map(problem, z_after) if kind_of(u) == kind]
        if not mb:
            continue
        cols = list(dict.fromkeys(k for _, c in mb for k in c))  # every record's bins (thermal: + time blocks)
        A = np.array([[c.get(k, np.nan) for k in cols] for _, c in mb])
        B = np.array([[c.get(k, np.nan) for k in cols] for _, c in ma])
        vmax = max(3.0, float(np.nanmax(A)))
        fig, axes = plt.subplots(1, 2, figsize=(13, 0.5 * len(mb) + 3), constrained_layout=True, sharey=True)
        for ax, M, lab in ((axes[0], A, "before (design under test)"), (axes[1], B, "after (final design)")):
            im = ax.imshow(M, aspect="auto", cmap="magma_r", vmin=0, vmax=vmax)
            ax.set_xticks(range(len(cols)), cols, rotation=60, ha="right", fontsize=7)
            ax.set_yticks(range(len(mb)), [u.key for u, _ in mb], fontsize=7)
            ax.set_title(lab)
            for (r, c), v in np.ndenumerate(M):
                if np.isfinite(v) and v >= 3:
                    ax.text(c, r, f"{v:.0f}", ha="center", va="center", fontsize=6, color="w" if v > vmax / 2 else "k")
        fig.colorbar(im, ax=axes, label="|measured - simulated| / noise (max over channels)")
        fig.suptitle(f"Localised residual map: record x {title}")
        p = out / f"heatmap_{kind}.png"
        fig.savefig(p, dpi=110)
        plt.close(fig)
        paths.append(p)
    return paths


def overlays(problem, signals, out) -> list:
    """Bin-mean force (and acceleration) per phase bin, measured vs before / after, one figure per sine unit."""
    paths = []
    for ui, u in enumerate(problem.units):
        if u.kind != "sine":
            continue
        sb, sa = signals[ui][0], signals[ui][1]
        if sb is None or sa is None:
            continue
        fig, axes = plt.subplots(1, len(u.channels), figsize=(6 * len(u.channels), 4), constrained_layout=True,
                                 squeeze=False)
        t = u.t
        m = t >= t[-1] - 1.0 / u.frequency
        scale, xl = (6e4, "flow [l/min]") if u.drive == F.FLOW else (1e3, "displacement [mm]")
        x = u.measured[u.drive][m] * scale
        for ax, ch in zip(axes[0], u.channels):
            # the measured curve on top, thick and dark: "after" often lies on it and must not hide it
            ax.plot(x, sb[ch][m], "--", color="0.55", lw=1, label="before", zorder=2)
            ax.plot(x, sa[ch][m], color="tab:green", lw=2.6, alpha=0.7, label="after", zorder=3)
            ax.plot(x, u.measured[ch][m], color="k", lw=0.9, label="measured", zorder=4)
            ax.set(xlabel=xl, ylabel=ch, title=f"{u.key}: last cycle")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
        p = out / f"overlay_{u.test}_{u.case}_{u.run}.png".replace("/", "_")
        fig.savefig(p, dpi=100)
        plt.close(fig)
        paths.append(p)
        if u.thermal and F.TEMP in sb and F.TEMP in sa:
            paths.append(_temperature_overlay(u, sb[F.TEMP], sa[F.TEMP], out))
    return paths


def _temperature_overlay(u, before, after, out):
    """Oil temperature rise over the record (each curve minus its mean over the reference window):
    thermocouple, design under test, final design."""
    ref = u.t < u.t[0] + 1.0
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    for y, style, col, lw, lab in ((before, "--", "0.55", 1.0, "before"), (after, "-", "tab:green", 2.6, "after"),
                                   (u.measured[F.TEMP], "-", "k", 0.9, "measured (thermocouple)")):
        ax.plot(u.t - u.t[0], y - np.mean(y[ref]), style, color=col, lw=lw, label=lab,
                alpha=0.7 if lab == "after" else 1.0)  # measured drawn last, thin and black
    ax.set(xlabel="time [s]", ylabel="oil temperature rise [K]", title=f"{u.key}: oil temperature")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    p = out / f"temperature_{u.test}_{u.case}_{u.run}.png".replace("/", "_")
    fig.savefig(p, dpi=100)
    plt.close(fig)
    return p


def _frame(u, sig: dict) -> pd.DataFrame:
    d = {"time [s]": u.t, "displacement [m]": u.measured["displacement [m]"], **sig}
    return pd.DataFrame(d)


def thesis_tables(problem, signals) -> str:
    """Table 6.5 / 6.6 layouts (kpi builders) for the mono-sine / random records present, before and after."""
    r65, r66 = {"before": [], "after": []}, {"before": [], "after": []}
    for ui, u in enumerate(problem.units):
        if u.test not in ("monosine", "random"):
            continue
        meas = _frame(u, {k: v for k, v in u.measured.items() if k != "displacement [m]"})
        for j, when in enumerate(("before", "after")):
            s = signals[ui][j]
            if s is None:
                continue
            sim = _frame(u, s)
            try:
                if u.test == "monosine":
                    ps = kpi.rod_acceleration_extremes(sim, u.frequency, 1)
                    pm = kpi.rod_acceleration_extremes(meas, u.frequency, 1)
                    row = {"no": len(r65[when]) + 1, "case": u.case, "current": u.current}
                    for h in ("rebound", "compression"):
                        for e in ("max", "min"):
                            row[f"sim_{h}_{e}"], row[f"meas_{h}_{e}"] = ps[f"{h} {e}"], pm[f"{h} {e}"]
                    r65[when].append(row)
                elif u.test == "random":
                    res = 2.0 if u.t[-1] - u.t[0] >= 2.0 else 4.0
                    ls, lm = kpi.psd_levels(sim, resolution=res), kpi.psd_levels(meas, resolution=res)
                    r66[when].append({"no": len(r66[when]) + 1, "case": u.case, "current": u.current,
                                      "sim_200": ls["200 Hz [dB]"], "meas_200": lm["200 Hz [dB]"],
                                      "sim_300": ls["300 Hz [dB]"], "meas_300": lm["300 Hz [dB]"]})
            except (ValueError, KeyError):
                continue
    parts = []
    for when in ("before", "after"):
        if r65[when]:
            parts.append(f"### Table 6.5 layout ({when}): mono-sine rod acceleration extremes [g]\n\n"
                         + kpi.to_markdown(kpi.table_6_5(r65[when])) + "\n")
        if r66[when]:
            parts.append(f"### Table 6.6 layout ({when}): random-test rod acceleration PSD [dB re 1 g^2/Hz]\n\n"
                         + kpi.to_markdown(kpi.table_6_6(r66[when])) + "\n")
    return "\n".join(parts) if parts else "(no mono-sine or random record used)\n"


def _resolvability_section(rs, misfit: bool = False) -> list:
    """`none` / `unexplained` verdicts: which library effects these records could have seen at their
    typical magnitude (``misfit``: each record's gate quantile times the Birge ratio of the
    calibrated design's misfit there, where above 1)."""
    if not rs:
        return []
    rows = [{"effect": r["effect"], "ratio": r["ratio"], "record": r["record"], "resolvable": r["resolvable"],
             "min factor": r["min_factor"]} for r in rs]
    if misfit:
        for row, r in zip(rows, rs):
            row.update({"ratio, noise alone": r["ratio_noise"], "record, noise alone": r["record_noise"]})
    for row, r in zip(rows, rs):
        row["separating test"] = r["separating_test"]
    text = ("Each candidate switched on at its typical magnitude: the chi^2 of its signature in its most affected "
            "record, after what the calibration pool and the bench allowances absorb, over that record's gate "
            "quantile. Below 1 the typical magnitude would not have been seen: `none` says nothing about that "
            "effect; about `min factor` x typical would be needed, or the test named.")
    if misfit:
        text = ("Each candidate switched on at its typical magnitude on the calibrated design: the chi^2 of its "
                "signature in its most affected record, after what the calibration pool and the bench allowances "
                "absorb, over that record's gate quantile times the record's Birge ratio (the chi^2 per feature "
                "of the misfit the calibrated design leaves there, less the candidate's own share of it, where "
                "above 1: the model error taken as extra scatter of that record). Below 1 the typical magnitude "
                "would hide under the model error of every record: `unexplained` says nothing about that "
                "effect; about `min factor` x typical would be needed. `ratio, noise alone` is the same test "
                "against the noise only.")
    return ["## What these records can resolve", "", text, "", _md_table(rows)]


def _named_lines(res: dict) -> list[str]:
    """Under a `named` verdict: how much of the held-out gap the named fit closes (the gate's
    fractions) and how often it wins the cycle bootstrap, so the name is read beside its reach."""
    st = res.get("stats", {}).get(res.get("named_fit"))
    if st is None:
        return []
    pct = lambda x: f"{100 * min(max(x, 0.0), 1.0):.0f} %"  # noqa: E731
    where = (f"{pct(st['closed_whole'])} of the whole held-out gap and {pct(st['closed_reached'])} of the excess in "
             f"the {len(st['reached'])} held-out record(s) its fitted effect reaches ({', '.join(st['reached'])})"
             if "reached" in st else f"{pct(st['closed'])} of the held-out gap")
    return [f"The named fit (`{res['named_fit']}`, refitted with the calibration parameters) closes {where}, "
            f"gains {st['gain']:.1f} in held-out chi^2 after its penalty and wins {pct(st['share'])} of the "
            "cycle bootstraps among the fits the closure gate passes. The gap table below is the whole "
            "held-out gap, calibration refit included.", ""]


def write_report(out, design, problem, res, doc, args) -> None:
    plots = out / "plots"
    plots.mkdir(parents=True, exist_ok=True)
    _, signals = problem.simulate([design, res["design"]], label="report", keep=True)
    zb = problem.zdiag(res["S0"])
    za = problem.zdiag(res["S_final"])
    figs = heatmaps(problem, zb, za, plots) + overlays(problem, signals, plots)
    g = doc["gap"]
    lines = [
        "# Discrepancy report", "",
        f"Design under test: `{args['design']}` (hash {design.hash()}); measured: `{args['measured']}`; "
        f"profile `{args['profile']}`, seed {args['seed']}.", "",
        f"## Verdict: **{doc['verdict']}**" + (f" - {', '.join(doc['effects'])}" if doc["effects"] else ""), "",
    ]
    lines += _named_lines(res)
    if doc["verdict"] == "ambiguous":
        lines += [f"Ambiguous group: {', '.join(doc['group'])}. Their signatures on the records present cannot be "
                  f"told apart; a {' or '.join(res.get('separating_tests', []))} record would separate them.", ""]
    lines += [
        "## Held-out gap", "",
        "Gap = RMS of the whitened residual (measured - simulated, divided by the noise estimated from the "
        "cycle-to-cycle scatter and the bench allowances) over the held-out features; 1 = noise level.", "",
        _md_table([{"before": g["before"], "after": g["after"], "closed fraction": g["closed_fraction"]}]),
        "Records: " + ", ".join(f"{u.key} ({u.fold}, {u.n_cycles} cycles/segments)" for u in problem.units), "",
        "## Where the model and the measurement disagree (design under test)", "",
        _md_table(doc["where"][:15]) if doc["where"] else "Nowhere beyond the listing threshold.\n",
        "## Candidates", "",
        "score = share of the training residual the candidate's signature explains (after the calibration "
        "directions are projected out); for a pair (a + b), the share of the cycle bootstraps it wins (0 when "
        "the closure gate left it out of the bootstrap: decision log).", "",
        _md_table([{"effect": c["effect"], "score": c["score"], "held-out gap before": c["heldout_gap_before"],
                    "held-out gap after": c["heldout_gap_after"],
                    "parameters": ", ".join(f"{k}={v:.3g}" for k, v in c["parameters"].items())}
                   for c in doc["candidates"]]),
        *_resolvability_section(res.get("resolvability"), bool(res.get("resolvability_misfit"))),
        "## Decision log", "",
        *[f"- {x}" for x in res["log"]], "",
        "## Thesis tables before / after", "",
        thesis_tables(problem, signals),
        "## Plots", "",
        *[f"![{p.stem}](plots/{p.name})" for p in figs], "",
        "## Notes", "",
        *[f"- {n}" for n in res.get("notes", [])],
        f"- simulations run: {problem.n_sims} (record x design)",
        *[f"- failed simulation batch: {x}" for x in dict.fromkeys(problem.failures)][:10],
        ("- Held-out records are other velocities / currents / tests than the fitted ones (alternating); the "
         "decision uses the held-out gain in chi^2 minus k ln(cycles) and a bootstrap over cycles."
         if not res.get("in_sample") else
         "- **No held-out record** (a single record, or flow-bench records only): every gap above is in-sample "
         "(the fitted records), and no effect is named on it."),
        f"- The augmented design is `{doc['design']}`.",
    ]
    (out / "report.md").write_text("\n".join(lines) + "\n")
