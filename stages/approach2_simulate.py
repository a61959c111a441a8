"""DVC stages `approach2_simulate` and `approach1_verification`: one design
through the approach-2 verification tests, each driven by the recorded
displacement of the measurement (thesis 6.5 / L1430):

    python stages/approach2_simulate.py approach2   # valves and compliance of approach2_fit,
                                                     # top mount of approach2_topmount (module test, thesis 7.2)
    python stages/approach2_simulate.py approach1   # the approach-1 design (results/approach1/designs/
                                                     # baseline_1.6.yaml), for the comparison only

Approach 2's own path (sensitivity, fit, top mount, this stage with
`approach2`) reads nothing of approach 1; only the comparison does. Tests:
- monosine16 (module, 16 Hz / 0.5 m/s / 10 mm, three currents; table 7.1),
- random (module, the road-noise records of the three baseline cases; table 7.2),
- verification (damper, pseudo-random; force, overfitting check L1561).
Force and acceleration pass the documented transducer bandwidths. The
module tests' recorded displacement is low-passed at report.RECORD_CUTOFF
(1 kHz: table 7.2 reads the PSD at 300 Hz); the verification record, like
the training record it checks, at conf/calibration/approach2.yaml
input_cutoff (its motion stays below 30 Hz).
-> results/approach2/sim/<approach1|approach2>/<test>.parquet."""

import sys

import pandas as pd

from _approach2 import CURRENTS, OUT2, approach1_design, approach2_design
from _common import CONF, config, config_hash, measured_dir, stage
from dampertwin.calibration.approach2 import input_cutoff
from dampertwin.design import yaml_load_file
from dampertwin.io import read_record, runs, write_frame
from dampertwin.protocols import load_protocol
from dampertwin.report import RECORD_CUTOFF, simulate_from_record
from dampertwin.sensors import sensor_lowpass

TESTS = {"monosine16": "module", "random": "module", "verification": "damper"}


def records(test: str):
    """(file, [(run label, current, record)]) of a test."""
    if test == "random":
        out = []
        for run, case in CURRENTS.items():
            df, _ = read_record(measured_dir() / "random" / f"{case}.parquet", "random", conf=CONF)
            out += [(run, float(g["current [A]"].iloc[0]), g) for _, g in runs(df)]
        return out
    df, _ = read_record(measured_dir() / test / "baseline.parquet", test, conf=CONF)
    return [(name, float(g["current [A]"].iloc[0]), g) for name, g in runs(df)]


DESIGNS = {"approach1": approach1_design, "approach2": approach2_design}


def main(name: str) -> None:
    cfg = config()
    if name not in DESIGNS:
        raise SystemExit(f"approach2_simulate.py: {name!r}; expected one of {', '.join(DESIGNS)}")
    designs = {name: DESIGNS[name]()}
    cal = yaml_load_file(CONF / "calibration" / "approach2.yaml")
    for test, conf_ in TESTS.items():
        proto = load_protocol(CONF / "test" / f"{test}.yaml")
        sensors = proto.get("sensors", {})
        cut = {"cutoff": input_cutoff(cal, {test: proto})} if conf_ == "damper" else {}
        recs = records(test)
        for name, design in designs.items():
            frames = []
            for run, cur, g in recs:
                r = simulate_from_record(design, g, conf_, cur, **cut)
                if not r.ok:
                    raise RuntimeError(f"{name}/{test}/{run}: simulation failed: {r.stats.message}")
                f = r.to_frame()
                fs = 1.0 / float(f["time [s]"].diff().mean())
                force = "top mount force [N]" if conf_ == "module" else "rod force [N]"
                cols = {"time [s]": f["time [s]"], "displacement [m]": f["displacement [m]"],
                        "force [N]": sensor_lowpass(f[force].to_numpy(), sensors.get("force"), fs),
                        "current [A]": cur}
                if conf_ == "module":
                    cols["rod acceleration [m/s^2]"] = sensor_lowpass(f["rod acceleration [m/s^2]"].to_numpy(),
                                                                      sensors.get("acceleration"), fs)
                frames.append(pd.DataFrame(cols).assign(run=run))
            write_frame(OUT2 / "sim" / name / f"{test}.parquet", pd.concat(frames, ignore_index=True),
                        {"synthetic": False, "simulated": True, "approach": name, "protocol": test,
                         "design_hash": design.hash(), "config_hash": config_hash(), "profile": cfg.profile.name,
                         "input": "recorded displacement of the measurement, low-passed",
                         "input_cutoff [Hz]": cut.get("cutoff", RECORD_CUTOFF), "sensors [Hz]": sensors})


if __name__ == "__main__":
    stage(main, "approach2_simulate" if sys.argv[1:] == ["approach2"] else "approach1_verification")
