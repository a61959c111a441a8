"""Submodel fits of ``dampertwin fit`` on records already read (no file I/O;
the command line's reading, defaults and writing are
:mod:`dampertwin.cli_fit`).

- :func:`fit_valve_records`      a valve's stiffness (and shim friction) on a
  flow-bench P-Q record (thesis eq. 6.1) by the study's flow-bench fit
  (:func:`~.approach1.fit_valve`: GA, least-squares polish, uncertainty), so
  the same record, settings and seed give the study stage's result;
- :func:`fit_compliance_records` gas content and oil bulk modulus on a
  damper-level sine test (eq. 6.2), GA;
- :func:`fit_topmount_records`   the top-mount parameters on a top-mount
  record (eq. 6.3), optionally the static curve by least squares first;
- :func:`friction_record`        a friction-device record for
  :func:`~.friction_fit.fit_friction_record` (LuGre, eq. 4.38-4.41).

Each GA fit returns ``(result, problem, sims)``: the fit.json dict (fitted
parameters with Gauss-Newton standard errors and 95 % intervals from the
residual Jacobian at the optimum, the objective, NRMSE per record fitted
and predicted, parameters on a search bound), the problem and its
simulations at the optimum (for plots).

NRMSE = RMS(simulated - measured) / (max - min of measured), per record.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..design import Design
from ..io import runs
from . import friction_fit as _ff
from .approach1 import (SHIM_VALVES, Channel, fit_static_curve, fit_valve, force_chain_nominal, record_input,
                        specs_from_config, through_sensor, valve_objective_name)
from .friction_fit import nrmse
from .ga import FitError, GASettings
from .problem import Problem, RecordsAbs

DEFAULT_POLISH = {"starts": 3, "max_nfev": 20}  # least-squares polish after the GA (calibration.polish)
DEFAULT_GA = {"population": 20, "reproduction_ratio": 80, "generations": 15, "mutation_probability": 10,
              "max_wall_s": 600.0}  # wall-time cap [s] of one population's simulations (issue 13)
VALVES = ("piston_rebound", "piston_intake", "base_compression", "base_intake")


class RecordProblem(Problem):
    """Records of one submodel test -> batch simulations / eq. 6.x objective
    of a design population (the GA fits of compliance and top mount, the
    NRMSE report of every GA fit). A calibration-core problem once its
    fitted ``keys`` are bound (:meth:`bind`): residuals measured - simulated
    over the fitted file's records (file 0), cost
    :class:`~.problem.RecordsAbs`."""

    def __init__(self, design: Design, configuration: str, channel, cases_per_file: list, sim_kw: dict,
                 nuisance: dict | None = None):
        self.design, self.configuration, self.channel = design, configuration, channel
        self.files = cases_per_file  # [(name, [(t, measured, excitation, extra), ...]), ...]
        self.sim_kw = sim_kw
        self.nuisance = dict(nuisance or {})  # nominal values of fitted sensor.* keys (the bench's chain)
        self.keys: list[str] = []

    def nominal(self, key: str) -> float:
        """Start value of a fitted key: the design's, or a sensor.* key's documented one."""
        return float(self.nuisance[key]) if key.startswith("sensor.") else float(self.design[key])

    def simulate(self, rows: list[dict], which=None):
        """{file index: [array(m, n_t) per case]} for designs with overrides ``rows``."""
        from ..simulation import simulate_batch

        designs = [self.design.with_overrides({k: v for k, v in r.items() if not k.startswith("sensor.")})
                   for r in rows]
        nuis = {k: np.array([r[k] for r in rows], float) for k in (rows[0] if rows else {}) if k.startswith("sensor.")}
        out = {}
        for fi, (_, cases) in enumerate(self.files):
            if which is not None and fi not in which:
                continue
            out[fi] = []
            for t, meas, ex, extra in cases:
                _, ch, status = simulate_batch(designs, ex, self.configuration, rate=1.0 / (t[1] - t[0]),
                                               duration=t[-1] - t[0], channels=list(self.channel.sources),
                                               **self.sim_kw, **extra)
                sim = np.asarray(self.channel(ch, nuis), float)[:, : len(t)]
                sim[status != 0] = np.nan
                out[fi].append(sim)
        return out

    def bind(self, keys) -> "RecordProblem":
        """Fit ``keys`` (the columns of a parameter row) on the fitted file (file 0)."""
        self.keys = list(keys)
        self.cost = RecordsAbs([c[0] for c in self.files[0][1]])
        return self

    def evaluate(self, X: np.ndarray) -> tuple[np.ndarray, list]:
        """Measured - simulated over the fitted file's records, row by parameter row; a reason per failed row."""
        sims = self.simulate([dict(zip(self.keys, row)) for row in np.atleast_2d(X)], which={0})
        R = np.hstack([meas[None, :] - sim for (_, meas, _, _), sim in zip(self.files[0][1], sims[0])])
        return R, [None if np.all(np.isfinite(r)) else "simulation failed" for r in R]

    def objective(self, keys):
        """Batch objective: sum over the fitted file's records of int |measured - simulated| dt (eq. 6.1-6.3)."""
        self.bind(keys)

        def f(X):
            return self.cost(self.evaluate(X)[0])

        return f


def _residual_stack(problem: RecordProblem, sims, fi: int, row: int) -> np.ndarray:
    return np.concatenate([s[row] - c[1] for s, c in zip(sims[fi], problem.files[fi][1])])


def jacobian_ci(problem: RecordProblem, best: dict, specs=None) -> dict:
    """Intervals of ``best`` from the fitted file's residual: Richardson
    central differences (:func:`~.uncertainty.central_jacobian`, steps 1e-3
    relative, one-sided at a search bound; one batch of 4p + 1 simulations
    at the uncertainty's tight tolerance, whose error estimate marks
    directions the Jacobian cannot resolve)."""
    from .polish import UNCERTAINTY_ATOL, UNCERTAINTY_RTOL
    from .uncertainty import central_jacobian, gauss_newton_ci

    keys = list(best)
    x = np.array([best[k] for k in keys], float)
    bounds = {s.key: (s.lo, s.hi) for s in (specs or [])}
    lo = np.array([bounds.get(k, (-np.inf, np.inf))[0] for k in keys], float)
    hi = np.array([bounds.get(k, (-np.inf, np.inf))[1] for k in keys], float)
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    scale = np.where(x != 0, np.abs(x), span)  # coordinates u = value / scale: steps of 1e-3 relative
    precise = type(problem)(problem.design, problem.configuration, problem.channel, problem.files,
                            {**problem.sim_kw, "rtol": UNCERTAINTY_RTOL, "atol": UNCERTAINTY_ATOL}, problem.nuisance)

    def batch(U):
        rows = [dict(zip(keys, u * scale)) for u in np.atleast_2d(U)]
        sims = precise.simulate(rows, which={0})
        return np.array([_residual_stack(precise, sims, 0, i) for i in range(len(rows))])

    r0, Ju, E = central_jacobian(batch, x / scale, 1e-3, lo / scale, hi / scale)
    J, E = Ju / scale, E / scale
    ok = np.all(np.isfinite(J), axis=1) & np.all(np.isfinite(E), axis=1) & np.isfinite(r0)
    return gauss_newton_ci(J[ok], r0[ok], keys, x, jac_error=E[ok])


def _fit_model(problem: RecordProblem, specs, label: str, submodel: str, settings, seed, extra_meta: dict,
               fixed_overrides: dict | None = None, determined_fn=None, scheduler=None):
    from .optimisers import run

    keys = [s.key for s in specs]
    x0 = {k: problem.nominal(k) for k in keys}
    res = run(problem.objective(keys), specs, settings, seed=seed, x0=x0, label=label, progress=True,
              scheduler=scheduler)
    ci = jacobian_ci(problem, dict(res.best), specs)
    if determined_fn is not None:
        extra_meta = {**extra_meta, "determined": determined_fn(res.best, ci)}
    return report(problem, res, specs, ci, submodel, settings, seed, extra_meta, fixed_overrides)


# NRMSE above which a fit is a miss, not a poor fit: the RMS error exceeds the record's whole measured range
# (real records fit to 0.02-0.3 in docs/validation; a kN column read as N gave 183)
MISS_NRMSE = 1.0


def _miss_flags(files: dict) -> list[str]:
    """A flag per file the optimum misses by more than its measured range (or cannot simulate)."""
    return [f"{path}: NRMSE {f['nrmse']:.3g} at the optimum: the model misses the {f['role']} record by more than "
            f"its measured range; check the record's units (e.g. kN read as N) and test" for path, f in files.items()
            if not f["nrmse"] <= MISS_NRMSE]


def report(problem: RecordProblem, res, specs, ci: dict, submodel: str, settings, seed, extra_meta: dict,
           fixed_overrides: dict | None = None):
    """(fit.json dict, problem, simulations at the optimum) of a GA fit:
    parameters, objective, intervals, NRMSE per file, parameters on a search
    bound (``bound_hits`` / ``flags``)."""
    sims = problem.simulate([dict(res.best)])
    files = {}
    for fi, (path, cases) in enumerate(problem.files):
        meas = np.concatenate([c[1] for c in cases])
        sim = np.concatenate([s[0] for s in sims[fi]])
        files[str(path)] = {"role": "fitted" if fi == 0 else "predicted", "nrmse": nrmse(meas, sim),
                            "records": len(cases), "samples": len(meas)}
    hits = res.bound_hits
    meta = dict(extra_meta)
    obj_name = meta.pop("objective_name", "int |measured - simulated| dt")
    result = {"submodel": submodel, **meta,
              "objective": {"name": obj_name, "start": res.start_objective, "best": res.best_objective,
                            "evaluations": res.evaluations, "failed_simulations": res.failed},
              "parameters": dict(res.best),
              "overrides": {**(fixed_overrides or {}), **{k: v for k, v in res.best.items()
                                                          if not k.startswith("sensor.")}},
              "bounds": {s.key: [s.lo, s.hi, s.scale] for s in specs}, "bound_hits": hits,
              "flags": [f"{h['parameter']} = {h['value']:.6g} ended on its {h['bound']} search bound "
                        f"{h['limit']:.6g}: the optimum may lie beyond it" for h in hits] + _miss_flags(files),
              "uncertainty": ci, "files": files, "nrmse": files[str(problem.files[0][0])]["nrmse"],
              "optimizer": f"GA (pygad) population {settings.population}, {settings.generations} generations, "
                           f"seed {seed}" + (", least-squares polish" if res.polish else "")}
    return result, problem, sims


def ga_settings(cfg: dict, population=None, generations=None) -> GASettings:
    """GA settings: DEFAULT_GA updated by ``cfg['ga']`` (a profile's), then by
    the command line's population / generations."""
    ga = {**DEFAULT_GA, **(cfg.get("ga") or {})}
    if population:
        ga["population"] = population
    if generations:
        ga["generations"] = generations
    return GASettings.from_config(ga, where=cfg.get("_ga_where", "GA settings"))


def search_specs(d: Design, items, prefix: str, where: str, nuisance: dict | None = None):
    """:func:`~.approach1.specs_from_config` with a FitError naming ``where``."""
    try:
        return specs_from_config(d, list(items), prefix=prefix, where=where, nuisance=nuisance)
    except ValueError as e:
        raise FitError(str(e)) from None


def _cases(frames, column: str, output: str, kind: str, cutoff: float, extra_of) -> list:
    """[(name, [(t, measured, excitation, extra) per run]) per record]."""
    files = []
    for name, f in frames:
        cases = []
        for _, g in runs(f):
            t, ex = record_input(g, column, kind, cutoff)
            cases.append((t, g[output].to_numpy(), ex, extra_of(g)))
        files.append((str(name), cases))
    return files


def fit_valve_records(design: Design, valve: str, frames, items, *, cutoff: float, bench: dict, settings: GASettings,
                      polish_settings, seed: int, where: str = "valve search space", scheduler=None,
                      objective: dict | None = None):
    """Fit one valve's stiffness a, b, c, d (and shim friction F_c) on
    flow-bench records ``frames`` [(name, frame), ...] (first fitted, the
    others predicted; ``flow [m^3/s]`` input, ``dp [Pa]`` output, eq. 6.1)
    by the study stage's function :func:`~.approach1.fit_valve` (GA, polish,
    uncertainty). ``items``: search items of the valve kind (as in
    conf/calibration/valves.yaml); ``cutoff`` [Hz]: input low-pass;
    ``bench``: upstream volume [m^3] and back pressure [Pa]; ``objective``:
    its weighting (:func:`~.approach1.valve_objective`; None: eq. 6.1)."""
    from .uncertainty import summary

    if valve not in VALVES:
        raise FitError(f"unknown valve {valve!r}; expected {', '.join(VALVES)}")
    kind = "shim" if valve in SHIM_VALVES else "intake"
    specs = search_specs(design, items, f"{valve}.", where)
    cal = {kind: [{"key": s.key, "bounds": [s.lo, s.hi], "scale": s.scale} for s in specs], "input_cutoff": cutoff,
           **({"objective": dict(objective)} if objective is not None else {})}
    try:
        obj_name, _ = valve_objective_name(cal, where)  # a bad objective names the config it came from
    except ValueError as e:
        raise FitError(str(e)) from None
    try:
        res = fit_valve(design, valve, frames[0][1], cal, settings, seed, bench=bench, progress=False,
                        polish_settings=polish_settings, scheduler=scheduler)
    except ValueError as e:
        raise FitError(str(e)) from None
    files = _cases(frames, "flow [m^3/s]", "dp [Pa]", "flow", cutoff, lambda g: {"bench_valve": valve})
    ch = Channel(("p upstream [Pa]", "p downstream [Pa]"), lambda c, nuis: c["p upstream [Pa]"] - c["p downstream [Pa]"])
    prob = RecordProblem(design, "valve", ch, files, {"bench": bench} if bench else {})
    unc = res.uncertainty
    ci = summary(unc) if "error" not in unc else {"error": unc["error"]}
    return report(prob, res, specs, ci, "valve", settings, seed,
                  {"valve": valve, "objective_name": obj_name,
                   "polish": res.polish, "bench": bench,
                   "determined": valve_determined(design, valve, res, specs, files[0][1], bench)})


def valve_determined(d: Design, valve: str, res, specs, cases, bench: dict) -> dict:
    """The valve's lift-force curve (eq. 4.19) over the lift range the
    fitted record reached (the fitted model's largest lift [m] driven by the
    record's own input), with its 95 % band
    (:func:`~.identifiability.valve_report`)."""
    from ..simulation import simulate_batch
    from .identifiability import valve_report

    fitted = d.with_overrides(res.best)
    lift = 0.0
    for t, _, ex, extra in cases:
        _, ch, status = simulate_batch([fitted], ex, "valve", rate=1.0 / (t[1] - t[0]), duration=t[-1] - t[0],
                                       channels=["lift [m]"], bench=bench or None, **extra)
        if status[0] == 0:
            lift = max(lift, float(np.nanmax(ch["lift [m]"][0])))
    return valve_report(fitted, valve, res.uncertainty, specs, lift)


def fit_compliance_records(design: Design, frames, items, *, cutoff: float, force_bandwidth: float | None,
                           settings: GASettings, seed: int, current: float | None = None,
                           where: str = "compliance search space", scheduler=None):
    """Fit gas content and oil bulk modulus (default) on damper-level sine
    records (displacement input, force output through the load cell's
    ``force_bandwidth`` [Hz], eq. 6.2); ``current`` [A] None: each run's."""
    nuis = force_chain_nominal(force_bandwidth)
    specs = search_specs(design, items, "", where, nuis)
    files = _cases(frames, "displacement [m]", "force [N]", "displacement", cutoff,
                   lambda g: {"current": current if current is not None else float(g["current [A]"].iloc[0])})
    fs = 1.0 / (files[0][1][0][0][1] - files[0][1][0][0][0])
    ch = through_sensor("rod force [N]", nuis["sensor.force_bandwidth"], fs)
    prob = RecordProblem(design, "damper", ch, files, {}, nuis)
    return _fit_model(prob, specs, "compliance", "compliance", settings, seed,
                      {"objective_name": "eq. 6.2 int |F_test - F_sim| dt [N*s]"}, scheduler=scheduler)


def fit_topmount_records(design: Design, frames, items, *, cutoff: float, force_bandwidth: float | None,
                         settings: GASettings, seed: int, static: dict | None = None, want=None, where_k: dict,
                         where: str = "top-mount search space", scheduler=None):
    """Fit the top-mount parameters on top-mount records (displacement input,
    force output, eq. 6.3). With ``static`` = {run, order[, input_cutoff]}
    (a run of the fitted record, as every run ``want`` names), the static curve is fitted by least
    squares first (kept only if it lowers eq. 6.3, as in the study); the GA
    uses the runs ``want`` (default: all but the static). ``where_k``:
    {frequencies [Hz], amplitude [m]} of the dynamic-stiffness report."""
    nuis = force_chain_nominal(force_bandwidth)
    specs = search_specs(design, items, "top_mount.", where, nuis)
    static = static or {}
    names = [n for n, _ in runs(frames[0][1])]
    missing = [r for r in [*(want or []), *([static["run"]] if static.get("run") is not None else [])] if r not in names]
    if missing:  # a run named in the config that the fitted record lacks: never silently skipped
        raise FitError(f"{frames[0][0]}: no run {', '.join(map(repr, missing))} (runs: {', '.join(map(str, names))}); "
                       f"the config's runs / dynamic_run / static.run name runs of the fitted record")
    files = []
    for p, f in frames:
        cases = []
        for name, g in runs(f):
            if (want and name not in want) or (not want and static.get("run") is not None and name == static["run"]):
                continue
            t, ex = record_input(g, "displacement [m]", "displacement", cutoff)
            cases.append((t, g["force [N]"].to_numpy(), ex, {}))
        if not cases:
            raise FitError(f"{p}: no record to fit (runs {names}; config runs {want})")
        files.append((str(p), cases))
    fs = 1.0 / (files[0][1][0][0][1] - files[0][1][0][0][0])
    ch = through_sensor("top mount force [N]", nuis["sensor.force_bandwidth"], fs)
    d, fixed, kept = design, {}, "design"
    if static.get("run") is not None:
        coef = fit_static_curve(frames[0][1], static["run"], int(static.get("order", 5)), design,
                                float(static.get("input_cutoff", 20.0)))
        keys = [s.key for s in specs]
        row = {k: RecordProblem(design, "topmount", ch, [], {}, nuis).nominal(k) for k in keys}
        j_nom = RecordProblem(design, "topmount", ch, files[:1], {}).objective(keys)(np.array([list(row.values())]))[0]
        d_ls = design.with_overrides({"top_mount.F_LD": coef})
        j_ls = RecordProblem(d_ls, "topmount", ch, files[:1], {}).objective(keys)(np.array([list(row.values())]))[0]
        if j_ls <= j_nom:
            d, fixed, kept = d_ls, {"top_mount.F_LD": coef}, "least squares"
    prob = RecordProblem(d, "topmount", ch, files, {}, nuis)

    def determined(best, ci):
        return top_mount_determined(d, best, ci, where_k)

    return _fit_model(prob, specs, "top mount", "topmount", settings, seed,
                      {"static_curve": kept, "objective_name": "eq. 6.3 int |F_test - F_sim| dt [N*s]"},
                      fixed_overrides=fixed, determined_fn=determined, scheduler=scheduler)


def top_mount_determined(d: Design, best: dict, ci: dict, where: dict) -> dict:
    """The fitted top mount's dynamic stiffness |K*| and loss angle at the
    test frequencies (``where``: {frequencies [Hz], amplitude [m], default
    1e-4}), with 95 % bands from the fit's covariance."""
    from .identifiability import top_mount_report

    return top_mount_report(d, best, ci, None, where["frequencies"], float(where.get("amplitude", 1e-4)))


def record_velocity(df: pd.DataFrame) -> np.ndarray:
    """Sliding velocity [m/s] of a record: the ``velocity [m/s]`` column if
    present, else the displacement differentiated (central differences)."""
    try:
        return _ff.record_velocity(df["time [s]"].to_numpy(float),
                                   df["displacement [m]"].to_numpy(float) if "displacement [m]" in df else None,
                                   df["velocity [m/s]"].to_numpy(float) if "velocity [m/s]" in df else None)
    except _ff.FrictionFitError as e:
        raise FitError(str(e)) from None


def friction_record(name, f: pd.DataFrame, velocity: str) -> dict:
    """A friction-device record {t [s], F [N], x [m] or None, v [m/s]};
    ``velocity`` 'record' (the velocity column if present) or
    'displacement' (always differentiate the displacement)."""
    for c in ("time [s]", "force [N]"):
        if c not in f:
            raise FitError(f"{name}: missing column {c!r} (friction record)")
    if velocity == "displacement" and "displacement [m]" not in f:
        raise FitError(f"{name}: --velocity displacement needs a 'displacement [m]' column")
    rec = {"t": f["time [s]"].to_numpy(float), "F": f["force [N]"].to_numpy(float),
           "x": f["displacement [m]"].to_numpy(float) if "displacement [m]" in f else None}
    rec["v"] = record_velocity(f.drop(columns=["velocity [m/s]"]) if velocity == "displacement" and
                               "velocity [m/s]" in f else f)
    return rec


def fit_friction_records(names, frames, base: dict, *, items=None, effects=(), holdout=None, seed: int = 0,
                         starts: int = 8, velocity: str = "record", fixed=(), where: str = "friction search space"):
    """The friction law (:func:`~.friction_fit.fit_friction_record`) fitted to
    the first record (``base``: values of the parameters not searched;
    ``fixed``: names kept out of the default search), the others predicted;
    ``where`` names the search items' source in errors. Returns (result, records, simulations)."""
    recs = [friction_record(p, f, velocity) for p, f in zip(names, frames)]
    try:
        result = _ff.fit_friction_record(recs[0], base, items=items, effects=tuple(effects), holdout=holdout,
                                         predicted=recs[1:], seed=seed, starts=starts, fixed=tuple(fixed),
                                         where=where)
    except _ff.FrictionFitError as e:
        raise FitError(str(e)) from None
    sims = result.pop("_sims")
    files = {str(names[0]): {"role": "fitted", "nrmse": result["nrmse"], "nrmse_held_out": result["nrmse_held_out"],
                             "nrmse_coulomb_viscous": result["baseline"]["nrmse"], "samples": len(recs[0]["F"])}}
    for p, q in zip(names[1:], sims["predicted"]):
        files[str(p)] = {"role": "predicted", **{k: v for k, v in q.items() if k != "_sim"}}
    result["files"] = files
    result["velocity"] = "record column" if velocity == "record" and "velocity [m/s]" in frames[0] else \
        "displacement differentiated"
    return result, recs, sims


__all__ = ["DEFAULT_GA", "DEFAULT_POLISH", "RecordProblem", "jacobian_ci", "report", "ga_settings", "search_specs",
           "fit_valve_records", "valve_determined", "fit_compliance_records", "fit_topmount_records",
           "top_mount_determined", "record_velocity", "friction_record", "fit_friction_records"]
