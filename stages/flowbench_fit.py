"""DVC stage `flowbench_fit@<valve design>`: GA fit of one valve's stiffness
(and shim friction) to its flow-bench P-Q record (thesis 6.2, eq. 6.1).

    python stages/flowbench_fit.py piston_rebound_lower
"""

import sys

import matplotlib.pyplot as plt

from _common import CONF, MEASURED, OUT, baseline, config, seed_for, write_json, write_overlay
from dampertwin import report
from dampertwin.calibration.approach1 import fit_valve
from dampertwin.calibration.ga import GASettings
from dampertwin.design import yaml_load
from dampertwin.io import read_frame, write_frame
from dampertwin.simulation import simulate
from dampertwin.protocols import build_runs, load_protocol
from dampertwin.variants import VALVE_DESIGNS, load_variant


def main(name: str) -> None:
    valve, case = VALVE_DESIGNS[name]
    cfg = config()
    d = baseline()
    if case:
        d = load_variant(CONF / "variant" / f"{case}.yaml").apply(d)
    cal = yaml_load((CONF / "calibration" / "valves.yaml").read_text())
    fb = load_protocol(CONF / "test" / "flowbench.yaml")
    bench = {"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]}
    meas, _ = read_frame(MEASURED / "flowbench" / f"{name}.parquet", "flowbench")
    out = OUT / "valves" / name
    seed = seed_for(f"flowbench_fit/{name}")
    res = fit_valve(d, valve, meas, cal, GASettings.from_config(cfg.profile.ga.valves), seed, bench=bench,
                    checkpoint=OUT / "checkpoints" / f"valve_{name}.npz", scheduler=cfg.profile.scheduler)
    meta = {"fit": "flowbench_fit", "valve": valve, "valve_design": name, "profile": cfg.profile.name, "seed": seed,
            "objective": "eq. 6.1 int|dp_test - dp_sim| dt [Pa*s]"}
    write_overlay(out / "overlay.yaml", res.best, meta)
    write_frame(out / "history.parquet", res.history.rename(columns={"best": "best [Pa*s]", "mean": "mean [Pa*s]"}),
                {**meta, "design_hash": d.hash()})
    write_json(out / "metrics.json", {"objective_start": res.start_objective, "objective_best": res.best_objective,
                                      "improvement_pct": 100 * (1 - res.best_objective / res.start_objective),
                                      "failed_simulations": res.failed, "evaluations": res.evaluations})
    fitted = d.with_overrides(res.best)
    run = next(r for r in build_runs(fb) if r.bench_valve == valve)
    sims = {}
    for label, dd in (("nominal", d), ("fitted", fitted)):
        sims[label] = simulate(dd, run.excitation, "valve", bench_valve=valve, rate=run.rate, bench=bench).to_frame()
    fig = report.pq_figure({valve: meas}, {valve: sims["fitted"]}, f"{name}: flow bench, measured vs fitted model")
    fig.savefig(out / "pq.png", dpi=100)
    plt.close(fig)
    (OUT / "checkpoints" / f"valve_{name}.npz").unlink(missing_ok=True)  # the fit is complete: its checkpoint is spent


if __name__ == "__main__":
    main(sys.argv[1])
