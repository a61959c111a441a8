"""What a fit determines where its coefficients trade off (issue 33).

The valve stiffness coefficients a, b, c, d (eq. 4.19) or the top mount's
AutoBushFD parameters (eq. 4.33-4.37) correlate pairwise near |1| on a
bench record: many coefficient sets draw the same curve. The curve is what
the record determines. This module propagates a fit's covariance
(:mod:`dampertwin.calibration.uncertainty`) to such quantities by the delta
method (first-order propagation, JCGM 100:2008 "GUM", sec. 5.1.2):
var(q) = g^T C g with g = dq/dtheta, 95 % band q +- t sqrt(var(q)) with
Student t on the fit's effective sample size.

- :func:`valve_lift_force`: the spring force F_k(x) = F_pre + a(e^{bx} - 1)
  + c(e^{dx} - 1) (eq. 4.19, THESIS-ERRATA 17) over the lift range the
  record reached;
- :func:`top_mount_dynamic_stiffness`: |K*| [N/m] and loss angle [deg] of
  the fitted top mount at test frequencies (first harmonic of a simulated
  sine, as :func:`dampertwin.kpi.dynamic_stiffness` measures them), with
  the gradient by central differences.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from ..model.valves import stiffness_force

VALVE_TERMS = ("F_preload", "a", "b", "c", "d")
CURVE_POINTS = 11  # lifts at which a lift-force curve is reported
REL_STEP = 1e-3  # relative step of the dynamic-stiffness gradient (central differences)


def covariance(unc: dict, specs=None) -> tuple[list[str], np.ndarray, float]:
    """Covariance [physical units] of a fit from its uncertainty report (the
    :meth:`~.uncertainty.Uncertainty.to_dict` form): the bounded covariance
    (directions the data do not resolve at the resolution limit of the
    Jacobian, so a quantity that depends on them gets a wide band, one that
    does not a finite one), each parameter widened by its sandwich / AR(1)
    ratio when > 1, as the reported intervals are. ``specs`` map gene
    coordinates to values (None: the coordinates are physical). Returns
    (keys, C, dof)."""
    rows = unc["parameters"]
    if isinstance(rows, dict):  # the summary form (gauss_newton_ci): parameter -> entry
        rows = [{"parameter": k, **v} for k, v in rows.items()]
    keys = [r["parameter"] for r in rows]
    C = np.array(unc["covariance_bounded"], float)
    w = np.array([max(1.0, r.get("sandwich / AR(1)", 1.0)) for r in rows], float)
    if specs is not None:
        by = {s.key: s for s in specs}
        d = []
        for r in rows:
            s = by[r["parameter"]]
            d.append(r["value"] * math.log(s.hi / s.lo) if s.scale == "log" else s.hi - s.lo)
        w = w * np.abs(np.array(d, float))
    n_eff = float(unc.get("n_eff", len(keys) + 2))
    return keys, C * np.outer(w, w), max(n_eff - len(keys), 1.0)


def _band(g: np.ndarray, C: np.ndarray, dof: float) -> float:
    var = float(g @ C @ g)
    return float(stats.t.ppf(0.975, dof)) * math.sqrt(max(var, 0.0)) if np.all(np.isfinite(C)) else math.inf


def valve_lift_force(values: dict, keys: list[str], C: np.ndarray, dof: float, lift_max: float,
                     n: int = CURVE_POINTS) -> list[dict]:
    """The spring force F_k [N] of one valve at ``n`` lifts from 0 to
    ``lift_max`` [m] with its 95 % band. ``values``: the valve's F_preload,
    a, b, c, d by short name; ``keys`` / ``C``: the fitted keys (``valve.a``
    or ``a``) and their covariance (others count as known)."""
    v = {k: float(values[k]) for k in VALVE_TERMS}
    idx = {k.split(".")[-1]: j for j, k in enumerate(keys)}
    rows = []
    for x in np.linspace(0.0, lift_max, n):
        eb, ed = math.exp(v["b"] * x), math.exp(v["d"] * x)
        grad = {"F_preload": 1.0, "a": eb - 1.0, "b": v["a"] * x * eb, "c": ed - 1.0, "d": v["c"] * x * ed}
        g = np.zeros(len(keys))
        for name, j in idx.items():
            g[j] = grad.get(name, 0.0)
        F = stiffness_force(float(x), v["F_preload"], v["a"], v["b"], v["c"], v["d"])
        h = _band(g, C, dof)
        rows.append({"lift [m]": float(x), "force [N]": float(F), "ci95 low [N]": F - h, "ci95 high [N]": F + h,
                     "rel. half-width [%]": 100 * h / abs(F) if F else math.inf})
    return rows


def top_mount_dynamic_stiffness(design, best: dict, keys: list[str], C: np.ndarray, dof: float,
                                frequencies, amplitude: float, cycles: int = 6, rate: float = 5000.0) -> list[dict]:
    """|K*| [N/m] and loss angle [deg] of the top mount with design
    overrides ``best`` at each frequency [Hz] for a sine of ``amplitude``
    [m], with 95 % bands from the covariance ``C`` of ``keys`` (``sensor.*``
    keys do not act on the mount and are skipped)."""
    from ..excitation import Excitation
    from ..kpi import harmonic
    from ..simulation import simulate_batch

    dk = [k for k in keys if not k.startswith("sensor.")]
    sel = [keys.index(k) for k in dk]
    Cd = C[np.ix_(sel, sel)]
    base = {k: float(v) for k, v in best.items() if not k.startswith("sensor.")}
    rows_designs = [base]
    for k in dk:
        h = REL_STEP * abs(base.get(k, design[k])) or REL_STEP
        for s in (1.0, -1.0):
            rows_designs.append({**base, k: base.get(k, float(design[k])) + s * h})
    designs = [design.with_overrides(r) for r in rows_designs]
    out = []
    for f in frequencies:
        t = np.arange(0.0, cycles / f, 1.0 / rate)
        x = amplitude * np.sin(2 * np.pi * f * t)
        _, ch, status = simulate_batch(designs, Excitation.from_samples(t, x), "topmount", rate=rate,
                                       duration=t[-1], channels=["top mount force [N]"])
        F = np.asarray(ch["top mount force [N]"], float)[:, : len(t)]
        m = t >= 1.0 / f  # all but the first cycle
        cx = harmonic(t[m], x[m], f)
        K = np.array([harmonic(t[m], Fi[m], f) / cx if s == 0 else np.nan for Fi, s in zip(F, status)])
        mag, ang = np.abs(K), np.degrees(np.angle(K))
        g_mag, g_ang = np.zeros(len(dk)), np.zeros(len(dk))
        for j, k in enumerate(dk):
            h = REL_STEP * abs(base.get(k, design[k])) or REL_STEP
            g_mag[j] = (mag[1 + 2 * j] - mag[2 + 2 * j]) / (2 * h)
            g_ang[j] = (ang[1 + 2 * j] - ang[2 + 2 * j]) / (2 * h)
        hm, ha = _band(g_mag, Cd, dof), _band(g_ang, Cd, dof)
        out.append({"frequency [Hz]": float(f), "amplitude [m]": amplitude, "stiffness [N/m]": float(mag[0]),
                    "stiffness ci95 [N/m]": [mag[0] - hm, mag[0] + hm],
                    "stiffness rel. half-width [%]": 100 * hm / mag[0] if mag[0] else math.inf,
                    "loss angle [deg]": float(ang[0]), "loss angle ci95 [deg]": [ang[0] - ha, ang[0] + ha]})
    return out


def valve_report(fitted, valve: str, unc: dict, specs, lift_max: float) -> dict:
    """The report entry of a valve fit: its lift-force curve up to
    ``lift_max`` [m] (the largest lift of the fitted model on the record)
    with 95 % bands. ``fitted``: the design with the fitted values; ``unc``
    / ``specs``: the fit's uncertainty (gene coordinates of ``specs``, or
    physical ones with ``specs`` None)."""
    if "error" in unc or not unc.get("parameters") or "covariance_bounded" not in unc:
        return {"error": unc.get("error", "no uncertainty analysis at the optimum")}
    keys, C, dof = covariance(unc, specs)
    values = {k: float(fitted[f"{valve}.{k}"]) for k in VALVE_TERMS}
    return {"quantity": "valve lift-force curve F_k(x) = F_pre + a(e^(bx) - 1) + c(e^(dx) - 1), eq. 4.19",
            "lift range [m]": [0.0, float(lift_max)], "curve": valve_lift_force(values, keys, C, dof, lift_max)}


def top_mount_report(design, best: dict, unc: dict, specs, frequencies, amplitude: float) -> dict:
    """The report entry of a top-mount fit: |K*| and loss angle at the test
    ``frequencies`` [Hz] for a sine of ``amplitude`` [m], with 95 % bands."""
    if "error" in unc or not unc.get("parameters") or "covariance_bounded" not in unc:
        return {"error": unc.get("error", "no uncertainty analysis at the optimum")}
    keys, C, dof = covariance(unc, specs)
    rows = top_mount_dynamic_stiffness(design, best, keys, C, dof, [float(f) for f in frequencies], float(amplitude))
    return {"quantity": "top mount dynamic stiffness |K*| and loss angle (first harmonic of a simulated sine)",
            "amplitude [m]": float(amplitude), "rows": rows}


def sweep_points(protocol: dict) -> tuple[list[float], float]:
    """Test frequencies [Hz] and the middle amplitude [m] of a top-mount
    protocol's dynamic-stiffness sweep."""
    sw = protocol["sweep"]
    amps = sorted(float(a) for a in sw["amplitudes"])
    return [float(f) for f in sw["frequencies"]], amps[len(amps) // 2]
