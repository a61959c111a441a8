"""DVC stage `compare`: thesis tables 6.5 (mono-sine rod acceleration peaks)
and 6.6 (random-test PSD at 200 / 300 Hz) for the ten design cases,
simulated (calibrated model) vs measured; metrics.json for `dvc metrics`,
plot data for `dvc plots` (+ the static plots/kpi_scatter.png and plots/index.html),
PNG overlays per case, the study report."""

import json

import matplotlib.pyplot as plt
import numpy as np

from _common import CONF, OUT, config, config_hash, read_overlay, write_json, write_text, measured_dir, params
from dampertwin import kpi, report
from dampertwin.design import yaml_load
from dampertwin.io import read_frame, read_record, runs, write_frame
from dampertwin.protocols import load_protocol
from dampertwin.calibration.uncertainty import summary
from dampertwin.study_report import build_report, kpi_points, plots_page, write_kpi_plots
from dampertwin.variants import load_variants


def main() -> None:
    cfg = config()
    f_mono = load_protocol(CONF / "test" / "monosine.yaml")["frequency"]
    cmp_cfg = yaml_load((CONF / "compare.yaml").read_text())
    n_tr = int(cmp_cfg["transient_cycles"])
    rows65, rows66, cases = [], [], []
    synthetic = False
    for v in load_variants(CONF / "variant"):
        sim_m = read_frame(OUT / "sim" / v.case / "monosine.parquet", "monosine")[0]
        mea_m, mmeta = read_record(measured_dir() / "monosine" / f"{v.case}.parquet", "monosine", conf=CONF)
        synthetic = synthetic or bool(mmeta.get("synthetic"))
        ps = kpi.rod_acceleration_extremes(sim_m, f_mono, n_tr)
        pm = kpi.rod_acceleration_extremes(mea_m, f_mono, n_tr)
        row = dict(no=v.row, case=v.title, current=v.current)
        for h in kpi.HALVES:
            for e in kpi.EXTREMES:
                for src, pk in (("sim", ps), ("meas", pm)):
                    row[f"{src}_{h}_{e}"], row[f"{src}_{h}_{e}_std"] = pk[f"{h} {e}"], pk[f"{h} {e} std"]
        rows65.append(row)
        sim_r = read_frame(OUT / "sim" / v.case / "random.parquet", "random")[0]
        mea_r = read_record(measured_dir() / "random" / f"{v.case}.parquet", "random", conf=CONF)[0]
        ls, lm = kpi.psd_levels(sim_r), kpi.psd_levels(mea_r)
        rows66.append(dict(no=v.row, case=v.title, current=v.current, sim_200=ls["200 Hz [dB]"],
                           meas_200=lm["200 Hz [dB]"], sim_300=ls["300 Hz [dB]"], meas_300=lm["300 Hz [dB]"]))
        cases.append(v.case)
        pdir = OUT / "plots" / v.case
        pdir.mkdir(parents=True, exist_ok=True)
        fig = report.monosine_figure(runs(sim_m)[0][1], runs(mea_m)[0][1], f_mono,
                                     f"{v.title}, {v.current:g} A: 13 Hz mono-sine, calibrated model vs measured")
        fig.savefig(pdir / "monosine.png", dpi=100)
        plt.close(fig)
        fig = report.psd_figure(sim_r, mea_r, f"{v.title}, {v.current:g} A: random road noise "
                                f"(Welch {ls['resolution [Hz]']:g} Hz)")
        fig.savefig(pdir / "psd.png", dpi=100)
        plt.close(fig)
    sim_c = read_frame(OUT / "sim" / "baseline_1.6" / "curving.parquet", "curving")[0]
    mea_c = read_record(measured_dir() / "curving" / "baseline.parquet", "curving", conf=CONF)[0]
    by_cur = {}
    for name, g in runs(sim_c):
        by_cur.setdefault(float(g["current [A]"].iloc[0]), []).append((name, g))
    fig = report.curving_figure(by_cur, mea_c, "Baseline: curving test at 0.32 / 0.9 / 1.6 A, calibrated model")
    fig.savefig(OUT / "plots" / "baseline_1.6" / "curving.png", dpi=100)
    plt.close(fig)

    t65, t66 = kpi.table_6_5(rows65), kpi.table_6_6(rows66)
    measured = params().get("measured", "data/measured")
    source = "measured data SYNTHETIC" if synthetic else f"measured data: {measured}"
    fl = cmp_cfg["flag"]
    flags = (kpi.flag_table_6_5(t65, rows65, float(fl["percent"]), float(fl["near_zero_g"]),
                                float(fl["scatter_sigmas"]))
             + kpi.flag_table_6_6(t66, float(fl["dB"])))
    flags65 = [f for f in flags if f["table"] == "6.5"]
    flags66 = [f for f in flags if f["table"] == "6.6"]
    n_cyc = int(ps["cycles"])
    definition = kpi.TABLE_6_5_DEFINITION.format(cycles=n_cyc, total=n_cyc + n_tr, transient=n_tr)
    meta = {"profile": cfg.profile.name, "seed": int(cfg.seed), "config_hash": config_hash(),
            "kpi": "thesis tables 6.5 / 6.6", "table_6_5_definition": definition,
            "psd": "Welch 2 Hz resolution, mean over a 10 Hz band, dB re 1 g^2/Hz"}
    write_frame(OUT / "table_6_5.parquet", t65, meta)
    write_frame(OUT / "table_6_6.parquet", t66, meta)
    write_text(OUT / "table_6_5.md", "Table 6.5 - mono-sine rod acceleration extremes, calibrated model vs measured "
               f"(profile {cfg.profile.name}; {source})\n\n" + kpi.flagged_markdown(t65, flags65)
               + f"\nDefinition: {definition}\n")
    write_text(OUT / "table_6_6.md", "Table 6.6 - PSD of rod acceleration at 200 / 300 Hz [dB re 1 g^2/Hz] "
               f"(profile {cfg.profile.name}; {source})\n\n" + kpi.flagged_markdown(t66, flags66))
    metrics = {}
    for col in (c for c in t65.columns if c.endswith("diff [%]")):
        a = np.abs(t65[col].to_numpy())
        metrics[col] = {"mean_abs": float(a.mean()), "max_abs": float(a.max())}
    for col in ("200 Hz diff [dB]", "300 Hz diff [dB]"):
        a = np.abs(t66[col].to_numpy())
        metrics[col] = {"mean_abs": float(a.mean()), "max_abs": float(a.max())}
    metrics["flags"] = {"count": len(flags), "thresholds": {k: float(v) for k, v in fl.items()}, "cells": flags}
    write_json(OUT / "metrics.json", metrics)
    write_kpi_plots(OUT, kpi_points(t65, t66, cases))
    write_json(OUT / "fits.json", fit_summary(cfg))
    build_report(OUT, measured_label=f"{measured}" + (" (SYNTHETIC: the virtual laboratory)" if synthetic else ""),
                 cases=cases)
    plots_page(OUT)


def fit_summary(cfg) -> dict:
    """Every fit's values, objective at the start / GA best / after polish,
    fitted nuisance values and the parameters its data cannot determine
    (uncertainty.md in its folder); committed with the tables, so the
    study's calibration can be read without the DVC cache."""
    fits = {"profile": cfg.profile.name, "fits": {}}
    for ov in sorted(OUT.glob("*/**/overlay.yaml")):
        name = str(ov.parent.relative_to(OUT))
        m = json.loads((ov.parent / "metrics.json").read_text())
        unc = ov.parent / "uncertainty.json"  # written by the fit (calibration.uncertainty at the polished optimum)
        u = json.loads(unc.read_text()) if unc.is_file() else {}
        fits["fits"][name] = {"values": read_overlay(ov), "objective_start": m["objective_start"],
                              "objective_ga": m.get("objective_ga"), "objective_polished": m.get("objective_polished"),
                              "objective_best": m["objective_best"], "failed_simulations": m["failed_simulations"],
                              "evaluations": m["evaluations"],
                              "uncertainty": summary(u) if u.get("parameters") else None,
                              "nuisance": m.get("nuisance", {}), "undetermined": m.get("undetermined"),
                              "bounds": m.get("bounds", {}), "bound_hits": m.get("bound_hits", []),
                              **({"determined": m["determined"]} if m.get("determined") else {}),
                              **({"valve_map": m["valve_map"]} if "valve_map" in m else {})}
    return fits


if __name__ == "__main__":
    main()
