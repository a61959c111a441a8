"""DVC stage `simulate@<case>`: the case's calibrated design through the
mono-sine and random tests (and, for baseline_1.6, the curving test at the
three currents), each driven by the recorded displacement of the
measurement. Force and acceleration pass the bench's documented transducer
bandwidths (conf/test/<test>.yaml `sensors`), so they compare with the
measurement through the same chain; the raw model signals are kept too.
Time series -> results/approach1/sim/<case>/<test>.parquet."""

import pandas as pd

from _common import CONF, OUT, config, config_hash, measured_dir, stage
from dampertwin.design import load
from dampertwin.io import read_record, runs, write_frame
from dampertwin.protocols import load_protocol
from dampertwin.sensors import sensor_lowpass
from dampertwin.report import simulate_from_record
from dampertwin.variants import check_current, load_variant

TESTS = {"monosine": "module", "random": "module", "curving": "damper"}


def main(case: str) -> None:
    design = load(OUT / "designs" / f"{case}.yaml")  # its P/Q map beside it (stage assemble)
    variant = load_variant(CONF / "variant" / f"{case}.yaml")
    check_current(variant.current, design, variant.path)
    cfg = config()
    tests = ["monosine", "random"] + (["curving"] if case == "baseline_1.6" else [])
    for test in tests:
        src = measured_dir() / test / f"{('baseline' if test == 'curving' else case)}.parquet"
        proto = load_protocol(CONF / "test" / f"{test}.yaml")
        sensors = proto.get("sensors", {})
        meas, mmeta = read_record(src, test, conf=CONF,
                                  current_range=(design.pq_map.currents[0], design.pq_map.currents[-1]))
        frames = []
        for name, g in runs(meas):
            cur = float(g["current [A]"].iloc[0]) if test == "curving" else variant.current
            r = simulate_from_record(design, g, TESTS[test], cur)
            if not r.ok:
                raise RuntimeError(f"{case}/{test}/{name}: simulation failed: {r.stats.message}")
            f = r.to_frame()
            force = "top mount force [N]" if TESTS[test] == "module" else "rod force [N]"
            fs = 1.0 / float(f["time [s]"].diff().mean())
            cols = {"time [s]": f["time [s]"], "displacement [m]": f["displacement [m]"],
                    "force [N]": sensor_lowpass(f[force].to_numpy(), sensors.get("force"), fs),
                    "force raw [N]": f[force], "current [A]": cur}
            if TESTS[test] == "module":
                cols["rod acceleration [m/s^2]"] = sensor_lowpass(f["rod acceleration [m/s^2]"].to_numpy(),
                                                                  sensors.get("acceleration"), fs)
                cols["rod acceleration raw [m/s^2]"] = f["rod acceleration [m/s^2]"]
                for v in ("piston_rebound", "piston_intake", "base_compression", "base_intake"):
                    cols[f"lift {v} [m]"] = f[f"lift {v} [m]"]
            frames.append(pd.DataFrame(cols).assign(run=name))
        write_frame(OUT / "sim" / case / f"{test}.parquet", pd.concat(frames, ignore_index=True),
                    {"synthetic": False, "simulated": True, "case": case, "protocol": test,
                     "design_hash": design.hash(), "config_hash": config_hash(), "profile": cfg.profile.name,
                     "measured_seed": mmeta.get("seed"),
                     "input": "recorded displacement of the measurement, low-passed",
                     "sensors [Hz]": sensors})


if __name__ == "__main__":
    stage(main, "simulate")
