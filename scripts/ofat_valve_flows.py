"""Where the oil goes in the 13 Hz / 10 mm mono-sine test (table 6.5) on the
nominal design and its one-valve variants: a diagnostic of issue 40 item 4
(why the lowered base valves barely move the project's 13 Hz peaks while the
thesis' model moves them by 0.8-3.7 g). Nothing is written; it prints, per
case at the case's current, the rod-acceleration extremes [g] of the last
cycle, and per valve the largest flow [l/min] and lift [mm] over the last two
cycles (nominal design = conf/design/baseline.yaml + conf/variant/<case>.yaml).

    PYTHONPATH=src python scripts/ofat_valve_flows.py [CASE ...]   (~10 s per case)
"""

from __future__ import annotations

import sys
from pathlib import Path

from dampertwin import kpi
from dampertwin.design import load
from dampertwin.protocols import build_runs, load_protocol
from dampertwin.simulation import simulate
from dampertwin.variants import load_variant

CONF = Path(__file__).resolve().parents[1] / "conf"
CASES = ("baseline_1.6", "lower_base_compression", "lower_base_intake")
FREQ = 13.0  # [Hz] conf/test/monosine.yaml


def main(cases) -> None:
    base = load(CONF / "design" / "baseline.yaml")
    runs = build_runs(load_protocol(CONF / "test" / "monosine.yaml"), seed=0)
    for case in cases:
        v = load_variant(CONF / "variant" / f"{case}.yaml")
        r = next(r for r in runs if abs(r.current - v.current) < 1e-9)
        df = simulate(v.apply(base), r.excitation, r.configuration, current=r.current, rate=r.rate).to_frame()
        last = df["time [s]"] > df["time [s]"].iloc[-1] - 2.0 / FREQ
        ext = kpi.rod_acceleration_extremes(df, FREQ)
        print(f"{case} ({v.current:g} A): rebound max {ext['rebound max']:.2f} g, "
              f"compression min {ext['compression min']:.2f} g")
        for col in (c for c in df.columns if c.startswith("flow ")):
            name = col[5:].rsplit(" [", 1)[0]
            lift = df.get(f"lift {name} [m]")
            extra = f", lift <= {lift[last].max() * 1e3:.4f} mm" if lift is not None else ""
            print(f"  {name:16s} flow {df[col][last].min() * 6e4:+7.2f} .. {df[col][last].max() * 6e4:+7.2f} l/min{extra}")


if __name__ == "__main__":
    main(sys.argv[1:] or CASES)
