"""DVC stage `sweep`: the table-6.5 OFAT sweep (ten design cases, calibrated
designs of the approach-1 study) -> results/sweeps/study_table65/ with its summary.
Same job function as `python -m dampertwin.sweep -m +ofat=table65`, composed
without @hydra.main; variants run in parallel on the local cores (joblib)."""

from joblib import Parallel, delayed

from _common import CONF, ROOT, stage
from dampertwin.errors import UserError
from dampertwin.sweep import run_variant, summarize, trend_agreement


def main() -> None:
    cases = sorted(p.stem for p in (CONF / "variant").glob("*.yaml"))
    cfgs = [compose_sweep([f"variant={c}", "sweep=study_table65"]) for c in cases]
    Parallel(n_jobs=2)(delayed(run_variant)(c, ROOT) for c in cfgs)
    tab = summarize(ROOT / "results" / "sweeps" / "study_table65")
    failed = int((tab.status != "ok").sum()) if len(tab) else 0
    if len(tab) == 0 or failed == len(tab):
        raise UserError(f"every variant of the sweep failed ({failed}); see "
                        f"{ROOT / 'results' / 'sweeps' / 'study_table65' / 'summary.md'}")
    agree, total = trend_agreement(tab)
    print(f"table 6.5 trend agreement with the thesis' measured column: {agree}/{total}")


def compose_sweep(overrides):
    from hydra import compose as h_compose
    from hydra import initialize_config_dir

    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        return h_compose(config_name="sweep", overrides=overrides)


if __name__ == "__main__":
    stage(main, "sweep")
