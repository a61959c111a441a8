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
    """A lab sample description (the shipped hidden sample's format) hiding ``effects``
    with ``values``; the part's deviations of ``base`` are kept only with
    ``keep_deviations`` (else the part is nominal plus ``factors`` / ``values``);
    the benches are ``base``'s.

    Lab-2 base (``factors`` / ``values`` / ``effects`` at the top): ``effects``
    names library effects (name -> True), ``values`` design keys and effect
    parameters (e.g. {"piston_leakage.gap": 6e-5}); the base's effects not
    named are switched off.

    Lab-3 base (a ``truth:`` section, measured on dampertwin.truth): the effects
    are the truth's own physics, written under ``truth.effects``. The hidden
    ones (truth.params.OFF_BY_DEFAULT: ``band_eccentricity``,
    ``two_node_thermal``, ``top_mount_free_play``, ``air_entrainment``) are off
    unless named; a case hides one as ``{name: True}`` (the truth's typical
    magnitude) or ``{name: {parameter: value}}`` (truth.params.EFFECT_PARAMETERS,
    SI, e.g. {"top_mount_free_play": {"clearance": 1.5e-4}}), and may set any
    truth key in ``values`` (e.g. {"chambers.BAND_H": 3e-5}, a worn band). The
    truth's always-on physics (shim friction, gas dissolution, ...) stays on
    unless ``effects`` switches it off; ``factors`` has no meaning there."""
    s = copy.deepcopy(base)
    if "truth" in s:
        if factors:
            raise ValueError("hidden_sample: a lab-3 (truth) sample has no factors; give truth values")
        t = s["truth"]
        if not keep_deviations:
            t["values"], t["effects"] = {}, {}
        t["values"] = {**t.get("values", {}), **(values or {})}
        t["effects"] = {**t.get("effects", {}), **(effects or {})}
        return s
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
