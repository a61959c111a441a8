"""Make the SYNTHETIC example files of examples/ (used by the documentation's
examples, which the test suite runs). Deterministic: same code, same bytes.

    python scripts/make_examples.py

- friction.parquet, friction_2.parquet: friction-device records from known
  LuGre parameters (F_c 20 N, F_s 35 N, k_b 4e5 N/m, s2 150 N*s/m) + 0.5 N noise;
- rig_monosine.csv: a rig export (ms, mm, kN, g, mA; ';' separated, decimal
  comma) of the baseline design's 13 Hz mono-sine at 1.6 A, simulated, with
  the mapping examples/mapping.yaml that imports it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from dampertwin.model.friction_only import simulate_friction
from dampertwin.io import write_frame

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "examples"
TRUE = dict(F_c=20.0, F_s=35.0, k_b=4e5, s2=150.0, c_comp=500.0, vd=0.001, a_s=0.01, alpha_s=2.0)


def friction(path: Path, seed: int, f1: float, duration: float, noise: float = 0.5) -> None:
    fs = 2000.0
    t = np.arange(0, duration, 1 / fs)
    x = 0.005 * np.sin(2 * np.pi * f1 * t) + 0.002 * np.sin(2 * np.pi * 1.7 * t)
    F = simulate_friction(t, np.gradient(x, t), **TRUE) + np.random.default_rng(seed).normal(0, noise, len(t))
    write_frame(path, pd.DataFrame({"time [s]": t, "displacement [m]": x, "force [N]": F}),
                {"synthetic": True, "truth": TRUE, "noise [N]": noise, "made_by": "scripts/make_examples.py"})


def rig_monosine(path: Path) -> None:
    from dampertwin.design import load
    from dampertwin.protocols import build_runs, load_protocol
    from dampertwin.simulation import simulate

    d = load(ROOT / "conf" / "design" / "baseline.yaml")
    run = next(r for r in build_runs(load_protocol(ROOT / "conf" / "test" / "monosine.yaml")) if r.current == 1.6)
    df = simulate(d, run.excitation, "module", current=1.6, rate=run.rate).to_frame()
    rig = pd.DataFrame({"Zeit": df["time [s]"] * 1e3, "Weg": df["displacement [m]"] * 1e3,
                        "Kraft": df["top mount force [N]"] / 1e3,
                        "Beschl": df["rod acceleration [m/s^2]"] / 9.80665})
    rig.round(6).to_csv(path, sep=";", decimal=",", index=False, lineterminator="\n")


if __name__ == "__main__":
    friction(OUT / "friction.parquet", seed=1, f1=0.5, duration=4.0)
    friction(OUT / "friction_2.parquet", seed=2, f1=0.8, duration=2.0)
    rig_monosine(OUT / "rig_monosine.csv")
