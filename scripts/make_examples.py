"""Make the SYNTHETIC example files of examples/ (used by the documentation's
examples, which the test suite runs). Deterministic: same code, same bytes.

    python scripts/make_examples.py

- friction.parquet, friction_2.parquet: friction-device records from known
  LuGre parameters (F_c 20 N, F_s 35 N, k_b 4e5 N/m, s2 150 N*s/m) + 0.5 N noise;
- rig_monosine.csv: a rig export (ms, mm, kN, g, mA; ';' separated, decimal
  comma) of the baseline design's 13 Hz mono-sine at 1.6 A, simulated, with
  the mapping examples/mapping.yaml that imports it;
- dyno_export.csv: a damper-dyno export (date-time stamps in ms, force [N],
  displacement [mm], temperature [degC]; 300 Hz, ';' separated, decimal
  comma) of a made-up passive damper (below), imported by
  examples/dyno_mapping.yaml.
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


# the made-up passive damper of dyno_export.csv: per direction a low-speed slope c0 [N*s/m] up to the knee
# v_k [m/s], then c1; plus Coulomb friction [N], a force lag [s] (loop area) and load-cell noise [N]
DYNO_DAMPER = {"rebound": (4000.0, 1200.0), "compression": (2000.0, 600.0), "knee [m/s]": 0.08,
               "friction [N]": 20.0, "lag [s]": 0.002, "noise [N]": 2.0}


def dyno_export(path: Path) -> None:
    from dampertwin.protocols.signals import velocity_steps

    fs, A, vs = 300.0, 0.0125, [0.05, 0.1, 0.2, 0.4]
    ex = velocity_steps(A, vs, 4, "sine")
    t = np.arange(0.0, ex.t_end, 1.0 / fs)
    te = ex.t0 + ex.dt * np.arange(len(ex.value))
    x = np.interp(t, te, ex.value)
    v = np.interp(t - DYNO_DAMPER["lag [s]"], te, ex.rate)
    vk = DYNO_DAMPER["knee [m/s]"]
    (r0, r1), (c0, c1) = DYNO_DAMPER["rebound"], DYNO_DAMPER["compression"]
    sp = np.abs(v)
    mag = np.where(v > 0, np.where(sp < vk, r0 * sp, r0 * vk + r1 * (sp - vk)),
                   np.where(sp < vk, c0 * sp, c0 * vk + c1 * (sp - vk)))
    rng = np.random.default_rng(38)
    F = np.sign(v) * (mag + DYNO_DAMPER["friction [N]"] * np.minimum(sp / 0.005, 1.0))
    F = F + rng.normal(0.0, DYNO_DAMPER["noise [N]"], len(t))
    P = np.abs(F * np.gradient(x, t))  # dissipated power [W] heats ~0.5 kg of oil and steel (~1 kJ/K) by its energy
    temp = 24.0 + np.cumsum(P) / fs / 1000.0 + rng.normal(0.0, 0.05, len(t))
    stamps = pd.Timestamp("2024-05-13 14:02:11.250") + pd.to_timedelta(np.round(t * 1e3), unit="ms")
    out = pd.DataFrame({"Zeitstempel": [s.strftime("%d.%m.%Y %H:%M:%S") + f",{s.microsecond // 1000:03d}" for s in stamps],
                        "Kraft": F.round(1), "Weg": (x * 1e3).round(3), "Temperatur": temp.round(2)})
    with open(path, "w") as f:
        f.write(f"# SYNTHETIC dyno export made by scripts/make_examples.py (a made-up passive damper: "
                f"{DYNO_DAMPER}); not a measurement\n")
        out.to_csv(f, sep=";", decimal=",", index=False, lineterminator="\n")


if __name__ == "__main__":
    friction(OUT / "friction.parquet", seed=1, f1=0.5, duration=4.0)
    friction(OUT / "friction_2.parquet", seed=2, f1=0.8, duration=2.0)
    rig_monosine(OUT / "rig_monosine.csv")
    dyno_export(OUT / "dyno_export.csv")
