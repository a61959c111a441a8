"""DVC stage `flowbench_fit@<valve design>`: GA fit of one valve's stiffness
(and shim friction) to its flow-bench P-Q record (thesis 6.2, eq. 6.1).

    python stages/flowbench_fit.py piston_rebound_lower
"""

import matplotlib.pyplot as plt

from _common import (CONF, OUT, baseline, checkpoint, checkpoint_store, choice, config, measured_dir, seed_for,
                     stage, staged_dir, write_fit)
from dampertwin import report
from dampertwin.calibration.approach1 import fit_valve, valve_objective_name
from dampertwin.calibration.ga import GASettings
from dampertwin.calibration.identifiability import valve_report
from dampertwin.design import yaml_load_file
from dampertwin.calibration.polish import PolishSettings
from dampertwin.io import read_record
from dampertwin.simulation import simulate
from dampertwin.protocols import build_runs, load_protocol
from dampertwin.variants import VALVE_DESIGNS, load_variant


def fit_record(d, valve: str, path, profile, seed: int, checkpoint=None):
    """The stage's fit of one flow-bench record file: the valves.yaml search
    space, the documented bench (conf/test/flowbench.yaml), the profile's
    GA and polish budgets (``profile``: a conf/profile mapping), through
    :func:`dampertwin.calibration.approach1.fit_valve` (as ``dampertwin fit
    valve``). Returns (FitResult, record, flow-bench protocol, bench)."""
    cal = yaml_load_file(CONF / "calibration" / "valves.yaml")
    fb = load_protocol(CONF / "test" / "flowbench.yaml")
    bench = {"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]}
    meas, _ = read_record(path, "flowbench", conf=CONF, valve=valve)
    res = fit_valve(d, valve, meas, cal, GASettings.from_config(profile["ga"]["valves"]), seed, bench=bench,
                    checkpoint=checkpoint, scheduler=profile.get("scheduler"),
                    polish_settings=PolishSettings.from_config(profile["polish"], "valves"))
    return res, meas, fb, bench


def main(name: str) -> None:
    valve, case = VALVE_DESIGNS[choice(name, VALVE_DESIGNS, "valve design")]
    cfg = config()
    d = baseline()
    if case:
        d = load_variant(CONF / "variant" / f"{case}.yaml").apply(d)
    out = OUT / "valves" / name
    seed = seed_for(f"flowbench_fit/{name}")
    res, meas, fb, bench = fit_record(d, valve, measured_dir() / "flowbench" / f"{name}.parquet", cfg.profile, seed,
                                      checkpoint=checkpoint_store(f"valve_{name}"))
    obj_name, obj_unit = valve_objective_name(yaml_load_file(CONF / "calibration" / "valves.yaml"))
    meta = {"fit": "flowbench_fit", "valve": valve, "valve_design": name, "profile": cfg.profile.name, "seed": seed,
            "objective": obj_name}
    run = next(r for r in build_runs(fb) if r.bench_valve == valve)
    sim = simulate(d.with_overrides(res.best), run.excitation, "valve", bench_valve=valve, rate=run.rate,
                   bench=bench)
    # what the record determines: the lift-force curve over the lift range of the test, with its band
    determined = valve_report(d.with_overrides(res.best), valve, res.uncertainty, res.specs,
                              float(sim.to_frame()["lift [m]"].max()))
    with staged_dir(out) as tmp:  # all outputs or none
        write_fit(tmp, res, meta, obj_unit, d.hash(), extra={"determined": determined})
        fig = report.pq_figure({valve: meas}, {valve: sim.to_frame()}, f"{name}: flow bench, measured vs fitted model")
        fig.savefig(tmp / "pq.png", dpi=100)
        plt.close(fig)
    checkpoint(f"valve_{name}").unlink(missing_ok=True)  # the fit is complete: its checkpoint is spent


if __name__ == "__main__":
    stage(main, "flowbench_fit")
