"""Calibration approach 1 (thesis chapter 6): isolated subsystem fits.

- valves on the flow bench, eq. 6.1: J = int |dp_test - dp_sim| dt,
  stiffness a, b, c, d and shim friction (table 6.1), GA table 6.2;
- compliance on the damper-level sine test, eq. 6.2: J = int |F_test - F_sim| dt,
  gas content and oil bulk modulus, GA table 6.3;
- top mount on its random record, eq. 6.3, parameters and limits of table
  6.4; the static curve by least squares (5th-order polynomial, thesis 7.2).

Every simulation is driven by the recorded input of the measurement (thesis
6.5), low-passed so sensor noise is not differentiated. No file I/O here.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..design import Design, DesignError
from ..errors import UserError
from ..excitation import Excitation
from ..io import runs
from ..sensors import sensor_lowpass
from ..simulation import simulate_batch
from .ga import Evaluator, FitResult, GASettings, ParamSpec, run_ga

SHIM_VALVES = ("piston_rebound", "base_compression")


def integral_abs_error(t: np.ndarray, measured: np.ndarray, simulated: np.ndarray) -> float:
    """int |measured - simulated| dt (eq. 6.1 - 6.3), trapezoidal; NaN if the
    simulation is incomplete."""
    e = np.abs(measured - simulated)
    if not np.all(np.isfinite(e)):
        return float("nan")
    return float(np.trapezoid(e, t))


def specs_from_config(design: Design, items: list, prefix: str = "",
                      where: str = "calibration config") -> list[ParamSpec]:
    """Search space: each item names a parameter and either absolute
    ``bounds`` or a ``window`` of factors on the nominal value; windows are
    clipped to the design's calibration bounds (thesis tables 6.1 / 6.4).
    A bad item raises UserError (a ValueError) naming ``where`` and the item."""
    specs = []
    if not isinstance(items, list) or not items:
        raise UserError(f"{where}: expected a non-empty list of parameters to fit")
    for i, it in enumerate(items):
        label = f"{where}: item {i} ({it!r})"
        if not isinstance(it, dict) or ("name" not in it and "key" not in it):
            raise UserError(f"{label}: needs 'name' (within the group) or 'key' (group.name)")
        if ("bounds" in it) == ("window" in it):
            raise UserError(f"{label}: give exactly one of 'bounds: [lo, hi]' or 'window: [f_lo, f_hi]'")
        if it.get("scale", "lin") not in ("lin", "log"):
            raise UserError(f"{label}: scale must be 'lin' or 'log'")
        key = prefix + it["name"] if "name" in it else it["key"]
        try:
            value = design[key]
            p = design.param(key) if not key.startswith("constants.") else None
        except KeyError as e:
            raise UserError(f"{label}: unknown design parameter {key!r}: {e}") from None
        rng = it.get("bounds", it.get("window"))
        if not (isinstance(rng, list) and len(rng) == 2 and all(isinstance(x, (int, float)) for x in rng)):
            raise UserError(f"{label}: bounds / window must be two numbers")
        if "bounds" in it:
            lo, hi = map(float, rng)
        else:
            a, b = (float(f) * value for f in rng)
            lo, hi = min(a, b), max(a, b)
            if p is not None and p.bounds is not None:
                lo, hi = max(lo, p.bounds[0]), min(hi, p.bounds[1])
        if not lo < hi:
            raise UserError(f"{label}: empty search interval for {key}: [{lo}, {hi}]")
        if it.get("scale") == "log" and lo <= 0:
            raise UserError(f"{label}: a log scale needs a positive lower bound, got {lo}")
        specs.append(ParamSpec(key, lo, hi, it.get("scale", "lin")))
    return specs


def _batch_objective(design: Design, specs, cases, configuration: str, channel, max_wall_s: float | None = None,
                     **sim_kw):
    """A batch objective over several records: sum of eq. 6.x integrals.
    Returns (values, reasons): a member whose design is invalid, whose
    simulation raises, stops early or yields non-finite output is NaN with
    its reason; the rest of the population is scored. Each simulate_batch
    call is capped at ``max_wall_s`` [s] (profile config)."""
    keys = [s.key for s in specs]

    def f(X: np.ndarray):
        n = len(X)
        designs: list = [None] * n
        reasons: list = [None] * n
        for i, row in enumerate(X):
            try:
                designs[i] = design.with_overrides(dict(zip(keys, map(float, row))))
            except DesignError as e:
                reasons[i] = "invalid design: " + "; ".join(e.errors)
        J = np.zeros(n)
        for t, measured, ex, extra in cases:
            live = [i for i in range(n) if reasons[i] is None]
            if not live:
                break
            sims = _simulate_members([designs[i] for i in live], ex, configuration, t, channel, max_wall_s,
                                     {**sim_kw, **extra})
            for i, (sim, why) in zip(live, sims):
                if why is None and len(sim) != len(t):
                    raise ValueError(f"simulated record has {len(sim)} samples, the measured one {len(t)}: "
                                     f"the simulation must cover the whole record (no truncation)")
                if why is None and not np.all(np.isfinite(sim)):
                    why = "simulation output not finite"
                if why is not None:
                    reasons[i] = why
                    continue
                J[i] += integral_abs_error(t, measured, sim)
        J[[i for i in range(n) if reasons[i] is not None]] = np.nan
        return J, reasons

    return f


def _simulate_members(designs, ex, configuration, t, channel, max_wall_s, kw) -> list[tuple]:
    """[(simulated channel, failure reason or None)] per design. One batch
    call; if it raises (one bad member must not lose the population), each
    member is run alone and the one that raises is marked with its error."""
    rate = 1.0 / (t[1] - t[0])
    if int(round((t[-1] - t[0]) * rate)) + 1 != len(t):  # jittered clock: the mean rate gives the record's length
        rate = (len(t) - 1) / (t[-1] - t[0])
    call = dict(rate=rate, duration=t[-1] - t[0], channels=list(channel.sources), max_wall_s=max_wall_s, **kw)
    try:
        _, ch, status = simulate_batch(designs, ex, configuration, **call)
        sim = channel(ch)
        return [(sim[i], None if status[i] == 0 else f"simulation stopped (status {int(status[i])}: "
                 f"step, wall-time ({max_wall_s} s) or solver failure)") for i in range(len(designs))]
    except Exception as e:  # noqa: BLE001 - isolate the failing member below
        if len(designs) == 1:  # a member's failure is its reason, not the end of the fit
            return [(None, f"simulation raised {type(e).__name__}: {' '.join(str(e).split())[:200]}")]
    return [m for d in designs for m in _simulate_members([d], ex, configuration, t, channel, max_wall_s, kw)]


class _Channel:
    def __init__(self, sources, fn):
        self.sources = sources
        self.fn = fn

    def __call__(self, ch):
        return self.fn(ch)


def _context(design: Design, measured: pd.DataFrame) -> str:
    """Hash of a fit's inputs (for checkpoint validity)."""
    import hashlib

    h = hashlib.sha256(design.hash().encode())
    h.update(pd.util.hash_pandas_object(measured, index=False).to_numpy().tobytes())
    return h.hexdigest()[:16]


def _run_of(measured: pd.DataFrame, run: str, where: str) -> pd.DataFrame:
    """The record of one run label; UserError listing the labels present."""
    rs = dict(runs(measured))
    if run not in rs:
        raise UserError(f"{where}: no run {run!r} in the measured record; runs present: {', '.join(map(str, rs))}")
    return rs[run]


def _need(cal: dict, key: str, where: str):
    if not isinstance(cal, dict) or key not in cal:
        raise UserError(f"{where}: missing key {key!r}")
    return cal[key]


def _record_input(df: pd.DataFrame, column: str, kind: str, cutoff: float):
    t = df["time [s]"].to_numpy()
    t = t - t[0]
    return t, Excitation.from_samples(t, df[column].to_numpy(), kind=kind, cutoff=cutoff)


def fit_valve(design: Design, valve: str, measured: pd.DataFrame, cal: dict, settings: GASettings, seed: int, *,
              bench: dict, checkpoint=None, scheduler=None, progress=True) -> FitResult:
    """Fit one valve's stiffness (and shim friction) to its flow-bench record."""
    kind = "shim" if valve in SHIM_VALVES else "intake"
    specs = specs_from_config(design, cal.get(kind), prefix=f"{valve}.",
                              where=f"conf/calibration/valves.yaml: {kind}")
    cases = []
    for _, g in runs(measured):
        t, ex = _record_input(g, "flow [m^3/s]", "flow", _need(cal, "input_cutoff", "conf/calibration/valves.yaml"))
        cases.append((t, g["dp [Pa]"].to_numpy(), ex, {"bench_valve": valve}))
    ch = _Channel(("p upstream [Pa]", "p downstream [Pa]"), lambda c: c["p upstream [Pa]"] - c["p downstream [Pa]"])
    f = _batch_objective(design, specs, cases, "valve", ch, settings.max_wall_s, bench=bench)
    x0 = {s.key: design[s.key] for s in specs}
    return run_ga(specs, Evaluator(f, scheduler), settings, seed, x0=x0, checkpoint=checkpoint,
                  label=f"valve {valve}", progress=progress, context=_context(design, measured))


def _through_sensor(column: str, bandwidth: float | None, fs: float) -> "_Channel":
    """Compare through the bench's measurement chain: the simulated signal
    passes the transducer's documented bandwidth (NaN rows left as they are)."""
    def fn(c):
        X = c[column]
        return np.array([sensor_lowpass(r, bandwidth, fs) if np.all(np.isfinite(r)) else r for r in X])

    return _Channel((column,), fn)


def fit_compliance(design: Design, measured: pd.DataFrame, cal: dict, settings: GASettings, seed: int, *,
                   checkpoint=None, scheduler=None, progress=True, force_bandwidth: float | None = None) -> FitResult:
    """Fit gas content and oil bulk modulus to the damper-level sine test;
    the simulated force passes the force transducer's bandwidth."""
    specs = specs_from_config(design, cal.get("parameters"), where="conf/calibration/compliance.yaml: parameters")
    cases = []
    for _, g in runs(measured):
        t, ex = _record_input(g, "displacement [m]", "displacement",
                              _need(cal, "input_cutoff", "conf/calibration/compliance.yaml"))
        cases.append((t, g["force [N]"].to_numpy(), ex, {"current": float(g["current [A]"].iloc[0])}))
    ch = _through_sensor("rod force [N]", force_bandwidth, 1.0 / (cases[0][0][1] - cases[0][0][0]))
    f = _batch_objective(design, specs, cases, "damper", ch, settings.max_wall_s)
    x0 = {s.key: design[s.key] for s in specs}
    return run_ga(specs, Evaluator(f, scheduler), settings, seed, x0=x0, checkpoint=checkpoint,
                  label="compliance", progress=progress, context=_context(design, measured))


def fit_static_curve(measured: pd.DataFrame, run: str, order: int = 5) -> list[float]:
    """Least-squares static load-deflection polynomial F = sum c_k X^k,
    k = 1..order (no constant), from a quasi-static record (thesis 7.2)."""
    g = _run_of(measured, run, "static curve")
    X = g["displacement [m]"].to_numpy()
    F = g["force [N]"].to_numpy()
    s = np.max(np.abs(X))
    A = np.column_stack([(X / s) ** k for k in range(1, order + 1)])
    c, *_ = np.linalg.lstsq(A, F, rcond=None)
    return [float(c[k - 1] / s**k) for k in range(1, order + 1)]


def fit_top_mount(design: Design, measured: pd.DataFrame, cal: dict, settings: GASettings, seed: int, *,
                  checkpoint=None, scheduler=None, progress=True,
                  force_bandwidth: float | None = None) -> tuple[FitResult, list[float], str]:
    """Static curve by least squares, then the dynamic parameters by GA on
    the random record (eq. 6.3). The least-squares curve is kept only if it
    lowers eq. 6.3 with the nominal dynamics (the quasi-static record also
    holds relaxation forces); otherwise the nominal curve stays. The fit thus
    never ends worse than the uncalibrated design. Returns (result, static
    curve coefficients, which curve was kept)."""
    where = "conf/calibration/topmount.yaml"
    static = _need(cal, "static", where)
    ls_coef = fit_static_curve(measured, _need(static, "run", where + ": static"),
                               _need(static, "order", where + ": static"))
    specs = specs_from_config(design, cal.get("parameters"), prefix="top_mount.",
                              where="conf/calibration/topmount.yaml: parameters")
    g = _run_of(measured, _need(cal, "dynamic_run", where), where + ": dynamic_run")
    t, ex = _record_input(g, "displacement [m]", "displacement", _need(cal, "input_cutoff", where))
    cases = [(t, g["force [N]"].to_numpy(), ex, {})]
    ch = _through_sensor("top mount force [N]", force_bandwidth, 1.0 / (t[1] - t[0]))
    x0 = {s.key: design[s.key] for s in specs}
    row0 = np.array([[x0[s.key] for s in specs]])
    d_ls = design.with_overrides({"top_mount.F_LD": ls_coef})
    j_nominal = float(_batch_objective(design, specs, cases, "topmount", ch, settings.max_wall_s)(row0)[0][0])
    j_ls = float(_batch_objective(d_ls, specs, cases, "topmount", ch, settings.max_wall_s)(row0)[0][0])
    if j_ls <= j_nominal:
        d, coef, kept = d_ls, ls_coef, "least squares (thesis 7.2)"
    else:
        d, coef, kept = design, list(design["top_mount.F_LD"]), "nominal (least squares raised eq. 6.3)"
    f = _batch_objective(d, specs, cases, "topmount", ch, settings.max_wall_s)
    res = run_ga(specs, Evaluator(f, scheduler), settings, seed, x0=x0, checkpoint=checkpoint,
                 label="top mount", progress=progress, context=_context(design, measured))
    res.start_objective = j_nominal  # "before" = the uncalibrated design: nominal curve and dynamics
    return res, coef, kept
