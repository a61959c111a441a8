"""DVC stage `approach2_tables`: thesis tables 7.1 (16 Hz mono-sine rod
acceleration peaks; Difference [%] = (measured - simulated) / |measured|)
and 7.2 (random-test PSD at 200 / 300 Hz; Difference [dB] =
|simulated - measured|) for the approach-2 design, the damper-force
verification on the pseudo-random signal (overfitting check, thesis L1561),
and a side-by-side table approach 1 vs approach 2 on the same lab data.
Outputs results/approach2/: table_7_1.*, table_7_2.*, verification.md,
side_by_side.md, metrics.json, plots/*.png."""

import json

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from _approach2 import CURRENTS, OUT2
from _common import CONF, config, config_hash, measured_dir, stage, write_json, write_text
from dampertwin import kpi
from dampertwin.calibration.approach2 import force_agreement
from dampertwin.calibration.ga import NEAR_BOUND
from dampertwin.design import yaml_load
from dampertwin.io import read_frame, read_record, runs, write_frame
from dampertwin.protocols import load_protocol

APPROACHES = ("approach1", "approach2")
PEAK_DEFINITION = ("Rod acceleration peak [g], + up: rebound = most positive value in the rebound half-cycle, "
                   "compression = most negative value in the compression half-cycle, averaged over the steady "
                   "cycles of the 16 Hz record (the first {n} left out as transient). Difference [%] = "
                   "(measured - simulated) / |measured| x 100 (thesis table 7.1 convention).")


def md(tab, digits=1):
    """Markdown of a table, the current printed as the thesis does (0.32, not 0.3)."""
    col = "Active valve current [A]"
    return kpi.to_markdown(tab.assign(**{col: tab[col].map("{:g}".format)}) if col in tab else tab, digits)


def flagged(tab, flags, digits=1):
    """:func:`md` with the cells above the flag thresholds marked [!n] and footnoted."""
    col = "Active valve current [A]"
    return kpi.flagged_markdown(tab.assign(**{col: tab[col].map("{:g}".format)}) if col in tab else tab, flags, digits)


def by_run(df):
    return {name: g for name, g in runs(df)}


def main() -> None:
    cfg = config()
    f16 = load_protocol(CONF / "test" / "monosine16.yaml")["frequency"]
    cmp_cfg = yaml_load((CONF / "compare.yaml").read_text())
    n_tr = int(cmp_cfg["transient_cycles"])
    fl = cmp_cfg["flag"]
    meas16, mmeta = read_record(measured_dir() / "monosine16" / "baseline.parquet", "monosine16", conf=CONF)
    synthetic = bool(mmeta.get("synthetic"))
    meas_ver, _ = read_record(measured_dir() / "verification" / "baseline.parquet", "verification", conf=CONF)
    meas_rnd = {run: read_record(measured_dir() / "random" / f"{case}.parquet", "random", conf=CONF)[0]
                for run, case in CURRENTS.items()}
    m16, mver = by_run(meas16), by_run(meas_ver)
    tables, ver_rows, metrics = {}, [], {}
    (OUT2 / "plots").mkdir(parents=True, exist_ok=True)
    for ap in APPROACHES:
        s16 = by_run(read_frame(OUT2 / "sim" / ap / "monosine16.parquet")[0])
        srnd = by_run(read_frame(OUT2 / "sim" / ap / "random.parquet")[0])
        sver = by_run(read_frame(OUT2 / "sim" / ap / "verification.parquet")[0])
        rows71, rows72 = [], []
        for no, run in enumerate(CURRENTS, 1):
            cur = float(m16[run]["current [A]"].iloc[0])
            ps, pm = kpi.rod_acceleration_extremes(s16[run], f16, n_tr), kpi.rod_acceleration_extremes(m16[run], f16, n_tr)
            rows71.append({"no": no, "current": cur, "sim_rebound": ps["rebound max"], "meas_rebound": pm["rebound max"],
                           "sim_compression": ps["compression min"], "meas_compression": pm["compression min"]})
            ls = kpi.psd_levels(srnd[run])
            lm = kpi.psd_levels(runs(meas_rnd[run])[0][1])
            rows72.append({"no": no, "current": cur, "sim_200": ls["200 Hz [dB]"], "meas_200": lm["200 Hz [dB]"],
                           "sim_300": ls["300 Hz [dB]"], "meas_300": lm["300 Hz [dB]"]})
            g, s = mver[run], sver[run]
            n = min(len(g), len(s))
            ver_rows.append({"approach": ap, "run": run, "current [A]": cur,
                             **force_agreement(g["time [s]"].to_numpy()[:n], g["force [N]"].to_numpy()[:n],
                                               s["force [N]"].to_numpy()[:n])})
            if ap == "approach2":
                fig, ax = plt.subplots(1, 2, figsize=(12, 4), constrained_layout=True)
                for lab_, df_ in (("measured", m16[run]), ("approach 2", s16[run])):
                    ax[0].plot(df_["time [s]"], df_["rod acceleration [m/s^2]"] / kpi.G, lw=0.7, label=lab_)
                ax[0].set(xlabel="time [s]", ylabel="rod acceleration [g]", title=f"16 Hz mono-sine, {cur:g} A")
                ax[1].plot(g["time [s]"], g["force [N]"], lw=0.6, label="measured")
                ax[1].plot(s["time [s]"], s["force [N]"], "--", lw=0.6, label="approach 2")
                ax[1].set(xlabel="time [s]", ylabel="damper force [N]", title=f"verification signal, {cur:g} A")
                for a in ax:
                    a.legend()
                    a.grid(alpha=0.3)
                fig.savefig(OUT2 / "plots" / f"verification_{run}.png", dpi=100)
                plt.close(fig)
        tables[ap] = (kpi.table_7_1(rows71), kpi.table_7_2(rows72))
    t71, t72 = tables["approach2"]
    ver = pd.DataFrame(ver_rows)
    source = "measured data SYNTHETIC (virtual lab)" if synthetic else f"measured data: {measured_dir()}"
    meta = {"profile": cfg.profile.name, "seed": int(cfg.seed), "config_hash": config_hash(),
            "table_7_1": PEAK_DEFINITION.format(n=n_tr), "table_7_2": "Welch 2 Hz, mean over a 10 Hz band, "
            "dB re 1 g^2/Hz; Difference [dB] = |simulated - measured| (thesis table 7.2 convention)"}
    note = "; ci profile: small GA budgets, the fit may be far from its optimum" if cfg.profile.name == "ci" else ""
    flags71 = kpi.flag_table_7(t71, "7.1", float(fl["percent"]), float(fl["dB"]), note)
    flags72 = kpi.flag_table_7(t72, "7.2", float(fl["percent"]), float(fl["dB"]), note)
    write_frame(OUT2 / "table_7_1.parquet", t71, meta)
    write_frame(OUT2 / "table_7_2.parquet", t72, meta)
    write_text(OUT2 / "table_7_1.md", f"Table 7.1 - 16 Hz mono-sine rod acceleration peaks, approach 2 vs measured "
               f"(profile {cfg.profile.name}; {source})\n\n" + flagged(t71, flags71)
               + "\nDefinition: " + PEAK_DEFINITION.format(n=n_tr) + "\n")
    write_text(OUT2 / "table_7_2.md", f"Table 7.2 - PSD of rod acceleration at 200 / 300 Hz [dB re 1 g^2/Hz], "
               f"approach 2 vs measured (profile {cfg.profile.name}; {source})\n\n" + flagged(t72, flags72)
               + "\nDifference [dB] = |simulated - measured| (thesis table 7.2 and 6.6 convention).\n")
    write_text(OUT2 / "verification.md", "Damper-force verification on the pseudo-random signal (thesis L1561; "
               f"{source})\n\n" + kpi.to_markdown(ver, 3))
    side = []
    for ap in APPROACHES:
        a71, a72 = tables[ap]
        v = ver[ver.approach == ap]
        side.append({"approach": ap,
                     "table 7.1 mean |diff| [%]": float(np.mean(np.abs(a71[[c for c in a71 if c.endswith("[%]")]]
                                                                         .to_numpy()))),
                     "table 7.2 mean |diff| [dB]": float(np.mean(a72[[c for c in a72 if "difference" in c]]
                                                               .to_numpy())),
                     "verification NRMSE mean [-]": float(v["nrmse [-]"].mean()),
                     "verification IAE sum [N*s]": float(v["iae [N*s]"].sum())})
    side = pd.DataFrame(side)
    write_text(OUT2 / "side_by_side.md", "Approach 1 vs approach 2 on the same lab data "
               f"(profile {cfg.profile.name}; {source}); lower is better\n\n" + kpi.to_markdown(side, 3)
               + "\nPer-approach tables 7.1 / 7.2:\n\n" + "".join(
                   f"### {ap}\n\n" + md(tables[ap][0]) + "\n" + md(tables[ap][1]) + "\n"
                   for ap in APPROACHES) + bound_section(OUT2 / "fit" / "metrics.json")
               + fixed_section(OUT2 / "fit" / "metrics.json"))
    for _, r in side.iterrows():
        metrics[r["approach"]] = {k: float(v) for k, v in r.items() if k != "approach"}
    metrics["bound_hits"] = json.loads((OUT2 / "fit" / "metrics.json").read_text()).get("bound_hits", [])
    fit = json.loads((OUT2 / "fit" / "metrics.json").read_text())
    metrics["valve_parameters"] = {"fitted": fit.get("fitted_valve_parameters"),
                                   "fixed_at_drawings": sorted(fit.get("fixed_at_drawings", {})),
                                   "why": fit.get("identifiability")}
    metrics["flags"] = {"count": len(flags71) + len(flags72), "thresholds": {k: float(v) for k, v in fl.items()},
                        "cells": flags71 + flags72}
    write_json(OUT2 / "metrics.json", metrics)


def bound_section(path) -> str:
    """Markdown: the approach-2 values that end on a search bound (or that none does)."""
    hits = json.loads(path.read_text()).get("bound_hits", [])
    if not hits:
        return "\nNo approach-2 value ends on its search bound.\n"
    rows = pd.DataFrame([{"parameter": h["parameter"], "value": h["value"], "bound": h["bound"], "limit": h["limit"]}
                         for h in hits])
    return ("\n### Approach-2 values on a search bound\n\nThe optimum may lie beyond the interval, or the "
            f"parameter stands in for an effect the model lacks (within {NEAR_BOUND:.0%} of the interval, in its "
            "own scale).\n\n"
            + kpi.to_markdown(rows, 4))


def fixed_section(path) -> str:
    """Markdown: the valve parameters approach 2 fitted and those it left at
    the drawings' values because the training record does not determine them."""
    m = json.loads(path.read_text())
    fitted, fixed = m.get("fitted_valve_parameters"), m.get("fixed_at_drawings")
    if fitted is None or fixed is None:
        return "\nThe approach-2 fit names no identifiability decision (an older fit): rerun `dvc repro`.\n"

    def by_valve(keys):
        out = {}
        for k in keys:
            v, p = k.split(".", 1)
            out.setdefault(v, []).append(p)
        return out

    f, x = by_valve(fitted), by_valve(fixed)
    rows = pd.DataFrame([{"valve": v, "fitted": ", ".join(f.get(v, [])) or "-",
                          "fixed at the drawings' value": ", ".join(x.get(v, [])) or "-"}
                         for v in dict.fromkeys([*f, *x])])
    return ("\n### Approach-2 valve parameters: fitted and fixed\n\nEach valve's table-6.1 parameters are fitted "
            "only where the training record determines them (95 % interval and correlation rule, "
            "conf/calibration/approach2.yaml `identifiability`); the others stay at the drawings' values. "
            f"Decision and figure: {m.get('identifiability')}.\n\n" + kpi.to_markdown(rows, 4))


if __name__ == "__main__":
    stage(main, "approach2_tables")
