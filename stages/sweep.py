"""DVC stage `sweep`: the table-6.5 OFAT sweep (ten design cases, calibrated
designs of the approach-1 study) -> results/sweeps/study_table65/ with its summary.
Same job function as `dampertwin sweep +ofat=table65`, composed
without @hydra.main; variants run in parallel on the local cores (joblib), or
on the Dask cluster the profile's `scheduler:` names."""

from functools import partial

from joblib import Parallel, delayed

from _common import CONF, ROOT, config, measured_dir, stage, write_json, write_text
from dampertwin import kpi
from dampertwin.errors import UserError
from dampertwin.protocols import load_protocol
from dampertwin.design import yaml_load_file
from dampertwin.sweep import (TREND_RESOLUTION, lab_peaks, run_variant, simulated_trend_table, summarize,
                              trend_metrics, trend_table)


def main() -> None:
    cases = sorted(p.stem for p in (CONF / "variant").glob("*.yaml"))
    cfgs = [compose_sweep([f"variant={c}", "sweep=study_table65"]) for c in cases]
    scheduler = config().profile.scheduler  # a Dask address: one variant per task on that cluster
    if scheduler:
        from dampertwin.parallel import DaskMap

        cluster = DaskMap(scheduler)
        try:
            cluster(partial(run_variant, root=ROOT), cfgs)
        finally:
            cluster.close()
    else:
        Parallel(n_jobs=2)(delayed(run_variant)(c, ROOT) for c in cfgs)
    out = ROOT / "results" / "sweeps" / "study_table65"
    tab = summarize(out)
    failed = int((tab.status != "ok").sum()) if len(tab) else 0
    if len(tab) == 0 or failed == len(tab):
        raise UserError(f"every variant of the sweep failed ({failed}); see {out / 'summary.md'}")
    f_mono = load_protocol(CONF / "test" / "monosine.yaml")["frequency"]
    trend = trend_table(tab, lab_peaks(measured_dir() / "monosine", f_mono))
    m = trend_metrics(trend)
    sim_trend = simulated_trend_table(tab, thesis_simulated(CONF / "thesis" / "published.yaml"))
    ms = trend_metrics(sim_trend)
    write_text(out / "trend.md", "# Table 6.5 trends: direction of |peak| change vs the baseline (1.6 A)\n\n"
               f"Simulated (calibrated designs) vs the thesis' measured column: {m['agree']}/{m['compared']} agree. "
               f"Changes below {TREND_RESOLUTION:g} g have no direction. The lab column is this study's (SYNTHETIC) "
               "measurement of its own sample; the reason is derived from the three changes.\n\n"
               + kpi.to_markdown(trend, digits=2)
               + "\n\n## Against the thesis' simulated column (its chapter-6 model)\n\n"
               f"Simulated (calibrated designs) vs the thesis' simulated column: {ms['agree']}/{ms['compared']} "
               "agree.\n\n" + kpi.to_markdown(sim_trend, digits=2))
    write_json(ROOT / "results" / "sweeps" / "metrics.json",
               {"table65_trend_agreement": m, "table65_trend_agreement_thesis_simulated": ms})
    print(f"table 6.5 trend agreement with the thesis' measured column: {m['agree']}/{m['compared']}, "
          f"with its simulated column: {ms['agree']}/{ms['compared']}")


def thesis_simulated(path) -> dict[str, tuple[float, float]]:
    """Table 6.5's simulated column from the thesis transcription: case -> (rebound, compression) [g]."""
    doc = yaml_load_file(path)
    try:
        return {r["case"]: (float(r["rebound"]["s"]), float(r["compression"]["s"])) for r in doc["table_6_5"]["rows"]}
    except (KeyError, TypeError, ValueError) as e:
        raise UserError(f"{path}: table_6_5.rows: expected case, rebound.s and compression.s per row ({e!r})") from None


def compose_sweep(overrides):
    from hydra import compose as h_compose
    from hydra import initialize_config_dir

    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        return h_compose(config_name="sweep", overrides=overrides)


if __name__ == "__main__":
    stage(main, "sweep")
