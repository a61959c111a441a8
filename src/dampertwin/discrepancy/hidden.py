"""Hidden-effect cases for testing the workflow (tests and bench/discrepancy.py):
lab sample descriptions with a hidden effect, and measurement artefacts the
effect library has no word for. Pure functions: dicts and frames in and out.
Everything produced here is SYNTHETIC."""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
from scipy import signal


def hidden_sample(base: dict, *, effects: dict | None = None, values: dict | None = None,
                  factors: dict | None = None, keep_deviations: bool = False) -> dict:
    """A lab sample description (the shipped hidden sample's format) hiding ``effects`` (name ->
    True) with ``values`` (effect parameters, e.g. {"piston_leakage.gap": 6e-5});
    the part's deviations of ``base`` are kept only with ``keep_deviations``
    (else the part is nominal plus ``factors``); the benches are ``base``'s."""
    s = copy.deepcopy(base)
    if not keep_deviations:
        s["factors"], s["values"], s["effects"] = {}, {}, {}
    s["factors"] = {**s.get("factors", {}), **(factors or {})}
    s["values"] = {**s.get("values", {}), **(values or {})}
    s["effects"] = {**{k: False for k in s.get("effects", {})}, **(effects or {})}
    return s


def accelerometer_resonance(df: pd.DataFrame, f0: float = 700.0, zeta: float = 0.08) -> pd.DataFrame:
    """A loose accelerometer mount: the rod acceleration passes a
    base-excited resonance at ``f0`` [Hz] with damping ratio ``zeta``
    (transmissibility (1 + (2 zeta s/w)) / (1 + 2 zeta s/w + (s/w)^2))."""
    out = df.copy()
    col = "rod acceleration [m/s^2]"
    if col not in out:
        return out
    parts = []
    for _, g in out.groupby("run", sort=False) if "run" in out else [(None, out)]:
        t = g["time [s]"].to_numpy()
        fs = 1.0 / float(np.mean(np.diff(t)))
        w = 2 * np.pi * f0
        b, a = signal.bilinear([2 * zeta / w, 1.0], [1 / w**2, 2 * zeta / w, 1.0], fs)
        x = g[col].to_numpy()
        parts.append(pd.Series(signal.lfilter(b, a, x - x[0]) + x[0], index=g.index))
    out[col] = pd.concat(parts)
    return out


def loadcell_crosstalk(df: pd.DataFrame, k: float = 0.02, lag: float = 0.0) -> pd.DataFrame:
    """A load cell with crosstalk from the actuator's displacement channel:
    force += k * (full-scale force / full-scale stroke) * displacement."""
    out = df.copy()
    if "force [N]" not in out or "displacement [m]" not in out:
        return out
    f, x = out["force [N]"].to_numpy(), out["displacement [m]"].to_numpy()
    scale = np.ptp(f) / max(np.ptp(x), 1e-12)
    out["force [N]"] = f + k * scale * (x - np.mean(x))
    return out
