"""One-command submodel fits on a bench record (``dampertwin fit ...``; the
command line's glue is :mod:`dampertwin.cli_fit`).

- ``fit_valve``      a valve's stiffness (and shim friction) on a flow-bench
                     P-Q record (thesis eq. 6.1), GA of calibration/approach1;
- ``fit_compliance`` gas content and oil bulk modulus on a damper-level sine
                     test (eq. 6.2), same GA;
- ``fit_topmount``   the top-mount parameters on a top-mount record (eq. 6.3),
                     optionally the static curve by least squares first;
- ``fit_friction``   the LuGre rod-friction law (eq. 4.38-4.41) on a
                     friction-device record (time, displacement, force), by a
                     friction-only simulation (``simulate_friction``) and
                     scipy least squares, with a Coulomb + viscous baseline.

Search bounds come from a config (YAML ``parameters:`` items, as in
conf/calibration/) or ``name=lo:hi`` strings, never from the damper's
design bounds. Each fit returns a dict (also written as ``out/fit.json``):
fitted parameters with Gauss-Newton standard errors and 95 % intervals from
the residual Jacobian at the optimum (inflated for autocorrelated
residuals: effective sample size from the lag-1 autocorrelation), the
objective, NRMSE per file (fitted and predicted), and plots in ``out/``.

NRMSE = RMS(simulated - measured) / (max - min of measured), per file.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pandas as pd

from .design import Design, load as load_design, yaml_load
from .calibration.approach1 import _record_input
from .fit_plots import friction_plots, series_plots
from .io import runs
from .calibration import friction_fit as _ff
from .calibration.friction_fit import coulomb_viscous_fit, nrmse  # noqa: F401  (re-exported)
from .model.friction_only import simulate_friction  # noqa: F401  (re-exported)
from .model.rod_friction import lugre

DEFAULT_POLISH = {"starts": 3, "max_nfev": 20}  # least-squares polish after the GA (calibration.polish)
DEFAULT_GA = {"population": 20, "reproduction_ratio": 80, "generations": 15, "mutation_probability": 10,
              "max_wall_s": 600.0}  # wall-time cap [s] of one population's simulations (issue 13)


from .calibration.ga import FitError  # noqa: E402  (the project's one fit error, re-exported)


# ---------------------------------------------------------------- friction model

def lugre_force(dv, z, *, F_c, F_s, k_b, s2, c_comp, vd, a_s, alpha_s):
    """LuGre rod friction (eq. 4.38-4.41) with keyword arguments named as in
    the design YAML. dv: sliding velocity [m/s], z: bristle deflection [m].
    Returns (dz/dt [m/s], force [N], positive opposing positive dv)."""
    return lugre(float(z), float(dv), k_b, F_c, F_s, s2, c_comp, vd, a_s, alpha_s)


def record_velocity(df: pd.DataFrame) -> np.ndarray:
    """Sliding velocity [m/s] of a record: the ``velocity [m/s]`` column if
    present, else the displacement differentiated (central differences)."""
    try:
        return _ff.record_velocity(df["time [s]"].to_numpy(float),
                                   df["displacement [m]"].to_numpy(float) if "displacement [m]" in df else None,
                                   df["velocity [m/s]"].to_numpy(float) if "velocity [m/s]" in df else None)
    except _ff.FrictionFitError as e:
        raise FitError(str(e)) from None


from .calibration.uncertainty import gauss_newton_ci  # noqa: E402  (re-exported)


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _write_json(path: Path, obj) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(json.dumps(obj, indent=2, sort_keys=False, default=float) + "\n")
    os.replace(tmp, path)
    return path


def _read(path, protocol=None, valve=None) -> pd.DataFrame:
    """A record through the project's one measurement reader (protocol rate, duration, labels, magnitudes,
    dead channels, force sign; ``protocol`` None: the one its metadata names, else a generic device record)."""
    from .io import read_record

    return read_record(Path(path), protocol, valve=valve, require=("time", "force", "displacement|velocity"))[0]


def _read_all(paths, protocol=None, valve=None) -> list[pd.DataFrame]:
    """Every measurement file a fit reads, in one call (one reader)."""
    return [_read(p, protocol, valve=valve) for p in paths]


# ---------------------------------------------------------------- friction fit

def _friction_record(path, f: pd.DataFrame, velocity: str) -> dict:
    for c in ("time [s]", "force [N]"):
        if c not in f:
            raise FitError(f"{path}: missing column {c!r} (friction record)")
    if velocity == "displacement" and "displacement [m]" not in f:
        raise FitError(f"{path}: --velocity displacement needs a 'displacement [m]' column")
    rec = {"t": f["time [s]"].to_numpy(float), "F": f["force [N]"].to_numpy(float),
           "x": f["displacement [m]"].to_numpy(float) if "displacement [m]" in f else None}
    rec["v"] = record_velocity(f.drop(columns=["velocity [m/s]"]) if velocity == "displacement" and
                               "velocity [m/s]" in f else f)
    return rec


def fit_friction(data, *, design: Design | str | os.PathLike | None = None, bounds: list[dict] | None = None,
                 predict=(), out: str | os.PathLike | None = None, seed: int = 0, starts: int = 8,
                 fixed: dict | None = None, effects=(), holdout_cycles: int | None = None,
                 velocity: str = "record") -> dict:
    """Fit the friction law (:mod:`dampertwin.calibration.friction_fit`) to a
    friction record (``time [s]``, ``displacement [m]``, ``force [N]``,
    optional ``velocity [m/s]``; force positive opposing positive velocity).
    ``bounds``: search items (name + bounds [+ scale]); default from the
    record's magnitudes. Parameters not searched come from ``fixed``, then
    from ``design`` (default conf baseline values). ``effects``: library
    effects added to the law (asymmetric, free_play). ``holdout_cycles``:
    cycles at the end of the record not fitted (default a third).
    ``velocity``: 'record' (the velocity column if present) or
    'displacement' (always differentiate the displacement)."""
    paths = [Path(data)] + [Path(p) for p in predict]
    frames = _read_all(paths)
    d = design if isinstance(design, Design) else load_design(design or _default_design())
    base = {k: float(d[_ff.FRICTION_KEYS[k]]) for k in _ff.FRICTION_KEYS}
    base.update({k: float(v) for k, v in (fixed or {}).items()})
    recs = [_friction_record(p, f, velocity) for p, f in zip(paths, frames)]
    try:
        result = _ff.fit_friction_record(recs[0], base, items=bounds, effects=tuple(effects), holdout=holdout_cycles,
                                         predicted=recs[1:], seed=seed, starts=starts)
    except _ff.FrictionFitError as e:
        raise FitError(str(e)) from None
    sims = result.pop("_sims")
    files = {str(paths[0]): {"role": "fitted", "nrmse": result["nrmse"], "nrmse_held_out": result["nrmse_held_out"],
                             "nrmse_coulomb_viscous": result["baseline"]["nrmse"], "sha256": _sha(paths[0]),
                             "samples": len(recs[0]["F"])}}
    for p, q in zip(paths[1:], sims["predicted"]):
        files[str(p)] = {"role": "predicted", **{k: v for k, v in q.items() if k != "_sim"}, "sha256": _sha(p)}
    result["files"] = files
    result["velocity"] = "record column" if velocity == "record" and "velocity [m/s]" in frames[0] else \
        "displacement differentiated"
    if out is not None:
        out = Path(out)
        _write_json(out / "fit.json", result)
        friction_plots(out, paths, recs, sims, result)
    return result


# ---------------------------------------------------------------- model-based fits (GA)

def _default_design() -> Path:
    from .config import repo_root

    try:
        return repo_root() / "conf" / "design" / "baseline.yaml"
    except FileNotFoundError:
        raise FitError("no --design given and no dampertwin repository here for the baseline design") from None


class _Problem:
    """Records of one submodel test -> batch residuals of a design population."""

    def __init__(self, design: Design, configuration: str, channel, cases_per_file: list, sim_kw: dict,
                 nuisance: dict | None = None):
        self.design, self.configuration, self.channel = design, configuration, channel
        self.files = cases_per_file  # [(path, [(t, measured, excitation, extra), ...]), ...]
        self.sim_kw = sim_kw
        self.nuisance = dict(nuisance or {})  # nominal values of fitted sensor.* keys (the bench's chain)

    def nominal(self, key: str) -> float:
        """Start value of a fitted key: the design's, or a sensor.* key's documented one."""
        return float(self.nuisance[key]) if key.startswith("sensor.") else float(self.design[key])

    def simulate(self, rows: list[dict], which=None):
        """{file index: [array(m, n_t) per case]} for designs with overrides ``rows``."""
        from .simulation import simulate_batch

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

    def objective(self, keys):
        from .calibration.approach1 import integral_abs_error

        def f(X):
            sims = self.simulate([dict(zip(keys, row)) for row in X], which={0})
            J = np.zeros(len(X))
            for (t, meas, _, _), sim in zip(self.files[0][1], sims[0]):
                J += np.array([integral_abs_error(t, meas, s) for s in sim])
            return J

        return f


def _residual_stack(problem: _Problem, sims, fi: int, row: int) -> np.ndarray:
    return np.concatenate([s[row] - c[1] for s, c in zip(sims[fi], problem.files[fi][1])])


def _jacobian_ci(problem: _Problem, best: dict, specs=None) -> dict:
    """Intervals of ``best`` from the fitted file's residual: Richardson
    central differences (:func:`~dampertwin.calibration.uncertainty.central_jacobian`,
    steps 1e-3 relative, one-sided at a search bound; one batch of 4p + 1
    simulations at the uncertainty's tight tolerance, whose error estimate
    marks directions the Jacobian cannot resolve)."""
    from .calibration.polish import UNCERTAINTY_ATOL, UNCERTAINTY_RTOL
    from .calibration.uncertainty import central_jacobian

    keys = list(best)
    x = np.array([best[k] for k in keys], float)
    bounds = {s.key: (s.lo, s.hi) for s in (specs or [])}
    lo = np.array([bounds.get(k, (-np.inf, np.inf))[0] for k in keys], float)
    hi = np.array([bounds.get(k, (-np.inf, np.inf))[1] for k in keys], float)
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    scale = np.where(x != 0, np.abs(x), span)  # coordinates u = value / scale: steps of 1e-3 relative
    precise = _Problem(problem.design, problem.configuration, problem.channel, problem.files,
                       {**problem.sim_kw, "rtol": UNCERTAINTY_RTOL, "atol": UNCERTAINTY_ATOL}, problem.nuisance)

    def batch(U):
        rows = [dict(zip(keys, u * scale)) for u in np.atleast_2d(U)]
        sims = precise.simulate(rows, which={0})
        return np.array([_residual_stack(precise, sims, 0, i) for i in range(len(rows))])

    r0, Ju, E = central_jacobian(batch, x / scale, 1e-3, lo / scale, hi / scale)
    J, E = Ju / scale, E / scale
    ok = np.all(np.isfinite(J), axis=1) & np.all(np.isfinite(E), axis=1) & np.isfinite(r0)
    return gauss_newton_ci(J[ok], r0[ok], keys, x, jac_error=E[ok])


def _fit_model(problem: _Problem, specs, out, label: str, submodel: str, settings, seed, extra_meta: dict,
               plot_fn=None, fixed_overrides: dict | None = None, determined_fn=None, scheduler=None) -> dict:
    from .calibration.optimisers import run

    keys = [s.key for s in specs]
    x0 = {k: problem.nominal(k) for k in keys}
    res = run(problem.objective(keys), specs, settings, seed=seed, x0=x0, label=label, progress=True,
              scheduler=scheduler)
    ci = _jacobian_ci(problem, dict(res.best), specs)
    if determined_fn is not None:
        extra_meta = {**extra_meta, "determined": determined_fn(res.best, ci)}
    return _report(problem, res, specs, ci, out, submodel, settings, seed, plot_fn, extra_meta, fixed_overrides)


def _report(problem: _Problem, res, specs, ci: dict, out, submodel: str, settings, seed, plot_fn, extra_meta: dict,
            fixed_overrides: dict | None = None) -> dict:
    """fit.json of a GA fit: parameters, objective, intervals, NRMSE per
    file, parameters on a search bound (``bound_hits`` / ``flags``)."""
    sims = problem.simulate([dict(res.best)])
    files = {}
    for fi, (path, cases) in enumerate(problem.files):
        meas = np.concatenate([c[1] for c in cases])
        sim = np.concatenate([s[0] for s in sims[fi]])
        files[str(path)] = {"role": "fitted" if fi == 0 else "predicted", "nrmse": nrmse(meas, sim),
                            "sha256": _sha(Path(path)), "records": len(cases), "samples": len(meas)}
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
                        f"{h['limit']:.6g}: the optimum may lie beyond it" for h in hits],
              "uncertainty": ci, "files": files, "nrmse": files[str(problem.files[0][0])]["nrmse"],
              "optimizer": f"GA (pygad) population {settings.population}, {settings.generations} generations, "
                           f"seed {seed}" + (", least-squares polish" if res.polish else "")}
    if out is not None:
        out = Path(out)
        _write_json(out / "fit.json", result)
        if plot_fn is not None:
            plot_fn(out, problem, sims)
    return result


def _settings(cfg: dict, population=None, generations=None):
    from .calibration.ga import GASettings

    ga = {**DEFAULT_GA, **(cfg.get("ga") or {})}
    if population:
        ga["population"] = population
    if generations:
        ga["generations"] = generations
    return GASettings.from_config(ga)


def _load(design) -> Design:
    return design if isinstance(design, Design) else load_design(design or _default_design())


def _flowbench_bench(cfg: dict) -> dict:
    """The flow bench's upstream volume [m^3] and back pressure [Pa]: the
    search config's ``bench:``, else the repository's documented bench
    (conf/test/flowbench.yaml), as the study's flow-bench stage uses."""
    if cfg.get("bench"):
        return dict(cfg["bench"])
    from .config import repo_root
    from .protocols import load_protocol

    try:
        fb = load_protocol(repo_root() / "conf" / "test" / "flowbench.yaml")
    except FileNotFoundError:
        return {}
    return {"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]}


def fit_valve(data, valve: str, *, design=None, bounds: list[dict] | None = None, predict=(), out=None,
              config: dict | None = None, seed: int = 0, population=None, generations=None, scheduler=None) -> dict:
    """Fit one valve's stiffness a, b, c, d (and shim friction F_c) on a
    flow-bench record (``flow [m^3/s]`` input, ``dp [Pa]`` output, eq. 6.1)
    by the study's flow-bench fit (:func:`dampertwin.calibration.approach1.fit_valve`:
    GA, then least-squares polish and the uncertainty at the optimum), so
    the same record, settings and seed give the study's result. Default
    search space: conf/calibration/valves.yaml's items for the valve kind,
    unless ``bounds`` / ``config['parameters']`` are given; GA and polish
    settings from ``config['ga']`` / ``config['polish']`` (a profile)."""
    from .calibration.approach1 import SHIM_VALVES, _Channel, fit_valve as study_fit_valve
    from .calibration.polish import PolishSettings
    from .calibration.uncertainty import summary

    d, cfg = _load(design), dict(config or {})
    if valve not in ("piston_rebound", "piston_intake", "base_compression", "base_intake"):
        raise FitError(f"unknown valve {valve!r}; expected piston_rebound, piston_intake, base_compression, "
                       "base_intake")
    kind = "shim" if valve in SHIM_VALVES else "intake"
    items = bounds or cfg.get("parameters") or _study_items("valves.yaml", kind)
    specs = _specs(d, items, f"{valve}.", cfg.get("_where", "valve search space"))
    cutoff = float(cfg.get("input_cutoff", _study_doc("valves.yaml").get("input_cutoff", 20.0)))
    bench = _flowbench_bench(cfg)
    frames = _read_all([data, *predict], "flowbench", valve=valve)
    settings = _settings(cfg, population, generations)
    polish_settings = PolishSettings.from_config(cfg.get("polish") or DEFAULT_POLISH)
    cal = {kind: [{"key": s.key, "bounds": [s.lo, s.hi], "scale": s.scale} for s in specs], "input_cutoff": cutoff}
    try:
        res = study_fit_valve(d, valve, frames[0], cal, settings, seed, bench=bench, progress=False,
                              polish_settings=polish_settings, scheduler=scheduler)
    except ValueError as e:
        raise FitError(str(e)) from None
    files = []
    for p, f in zip([data, *predict], frames):
        cases = []
        for _, g in runs(f):
            t, ex = _record_input(g, "flow [m^3/s]", "flow", cutoff)
            cases.append((t, g["dp [Pa]"].to_numpy(), ex, {"bench_valve": valve}))
        files.append((str(p), cases))
    ch = _Channel(("p upstream [Pa]", "p downstream [Pa]"), lambda c, nuis: c["p upstream [Pa]"] - c["p downstream [Pa]"])
    prob = _Problem(d, "valve", ch, files, {"bench": bench} if bench else {})

    def plots(o, problem, sims):
        series_plots(o, problem, sims, "dp [Pa]", "valve",
                      x_of=lambda t, ex, extra: (np.interp(t, ex.t0 + ex.dt * np.arange(len(ex.value)), ex.value)
                                                 * 60000.0, "flow [l/min]"))

    unc = res.uncertainty
    ci = summary(unc) if "error" not in unc else {"error": unc["error"]}
    return _report(prob, res, specs, ci, out, "valve", settings, seed, plots,
                   {"valve": valve, "objective_name": "eq. 6.1 int |dp_test - dp_sim| dt [Pa*s]",
                    "polish": res.polish, "bench": bench,
                    "determined": valve_determined(d, valve, res, specs, files[0][1], bench)})


def valve_determined(d: Design, valve: str, res, specs, cases, bench: dict) -> dict:
    """The valve's lift-force curve (eq. 4.19) over the lift range the
    fitted record reached (the fitted model's largest lift), with its 95 %
    band (:func:`dampertwin.calibration.identifiability.valve_report`)."""
    from .calibration.identifiability import valve_report
    from .simulation import simulate_batch

    fitted = d.with_overrides(res.best)
    lift = 0.0
    for t, _, ex, extra in cases:
        _, ch, status = simulate_batch([fitted], ex, "valve", rate=1.0 / (t[1] - t[0]), duration=t[-1] - t[0],
                                       channels=["lift [m]"], bench=bench or None, **extra)
        if status[0] == 0:
            lift = max(lift, float(np.nanmax(ch["lift [m]"][0])))
    return valve_report(fitted, valve, res.uncertainty, specs, lift)


def fit_compliance(data, *, design=None, bounds=None, predict=(), out=None, config=None, seed=0,
                   current: float | None = None, population=None, generations=None, scheduler=None) -> dict:
    """Fit gas content and oil bulk modulus (default) on a damper-level sine
    record (displacement input, force output, eq. 6.2)."""
    from .calibration.approach1 import _record_input, _through_sensor

    d, cfg = _load(design), dict(config or {})
    items = bounds or cfg.get("parameters") or _study_items("compliance.yaml", "parameters")
    nuis = _documented_force_chain(cfg, "compliance.yaml")
    specs = _specs(d, items, "", cfg.get("_where", "compliance search space"), nuis)
    cutoff = float(cfg.get("input_cutoff", 1000.0))
    files = []
    for p in [data, *predict]:
        cases = []
        for _, g in runs(_read(p, "compliance" if current is None else None)):
            t, ex = _record_input(g, "displacement [m]", "displacement", cutoff)
            cur = current if current is not None else float(g["current [A]"].iloc[0])
            cases.append((t, g["force [N]"].to_numpy(), ex, {"current": cur}))
        files.append((str(p), cases))
    fs = 1.0 / (files[0][1][0][0][1] - files[0][1][0][0][0])
    ch = _through_sensor("rod force [N]", nuis["sensor.force_bandwidth"], fs)
    prob = _Problem(d, "damper", ch, files, {}, nuis)

    def plots(o, problem, sims):
        series_plots(o, problem, sims, "rod force [N]", "compliance")

    return _fit_model(prob, specs, out, "compliance", "compliance", _settings(cfg, population, generations), seed,
                      {"objective_name": "eq. 6.2 int |F_test - F_sim| dt [N*s]"}, plots, scheduler=scheduler)


def fit_topmount(data, *, design=None, bounds=None, predict=(), out=None, config=None, seed=0,
                 population=None, generations=None, scheduler=None) -> dict:
    """Fit the top-mount parameters on a top-mount record (displacement
    input, force output, eq. 6.3). With ``config['static'] = {run, order}``
    and that run in the record, the static curve is fitted by least squares
    first (kept only if it lowers eq. 6.3, as in the study); the GA then
    uses the runs named in ``config['runs']`` (or ``config['dynamic_run']``,
    as in conf/calibration/topmount.yaml; default: all but the static)."""
    from .calibration.approach1 import _record_input, _through_sensor, fit_static_curve

    d, cfg = _load(design), dict(config or {})
    items = bounds or cfg.get("parameters") or _study_items("topmount.yaml", "parameters")
    nuis = _documented_force_chain(cfg, "topmount.yaml")
    specs = _specs(d, items, "top_mount.", cfg.get("_where", "top-mount search space"), nuis)
    cutoff = float(cfg.get("input_cutoff", 500.0))
    meas0 = _read(data, "topmount")
    static = cfg.get("static") or {}
    names = [n for n, _ in runs(meas0)]
    fixed = {}
    want = cfg.get("runs") or ([cfg["dynamic_run"]] if cfg.get("dynamic_run") else None)
    files = []
    for p in [data, *predict]:
        cases = []
        for name, g in runs(_read(p, "topmount")):
            if (want and name not in want) or (not want and static.get("run") is not None and name == static["run"]):
                continue
            t, ex = _record_input(g, "displacement [m]", "displacement", cutoff)
            cases.append((t, g["force [N]"].to_numpy(), ex, {}))
        if not cases:
            raise FitError(f"{p}: no record to fit (runs {names}; config runs {want})")
        files.append((str(p), cases))
    fs = 1.0 / (files[0][1][0][0][1] - files[0][1][0][0][0])
    ch = _through_sensor("top mount force [N]", nuis["sensor.force_bandwidth"], fs)
    kept = "design"
    if static.get("run") is not None and static["run"] in names:
        coef = fit_static_curve(meas0, static["run"], int(static.get("order", 5)), d,
                                float(static.get("input_cutoff", 20.0)))
        keys = [s.key for s in specs]
        row = {k: _Problem(d, "topmount", ch, [], {}, nuis).nominal(k) for k in keys}
        j_nom = _Problem(d, "topmount", ch, files[:1], {}).objective(keys)(np.array([list(row.values())]))[0]
        d_ls = d.with_overrides({"top_mount.F_LD": coef})
        j_ls = _Problem(d_ls, "topmount", ch, files[:1], {}).objective(keys)(np.array([list(row.values())]))[0]
        if j_ls <= j_nom:
            d, fixed, kept = d_ls, {"top_mount.F_LD": coef}, "least squares"
    prob = _Problem(d, "topmount", ch, files, {}, nuis)

    def plots(o, problem, sims):
        series_plots(o, problem, sims, "top mount force [N]", "topmount")

    def determined(best, ci):
        return top_mount_determined(d, best, ci, cfg.get("determined"))

    return _fit_model(prob, specs, out, "top mount", "topmount", _settings(cfg, population, generations), seed,
                      {"static_curve": kept, "objective_name": "eq. 6.3 int |F_test - F_sim| dt [N*s]"}, plots,
                      fixed_overrides=fixed, determined_fn=determined, scheduler=scheduler)


def top_mount_determined(d: Design, best: dict, ci: dict, where: dict | None = None) -> dict:
    """The fitted top mount's dynamic stiffness |K*| and loss angle at the
    test frequencies (``where``: {frequencies [Hz], amplitude [m]}; default
    the documented sweep of conf/test/topmount.yaml, middle amplitude), with
    95 % bands from the fit's covariance."""
    from .calibration.identifiability import sweep_points, top_mount_report

    where = dict(where or {})
    if "frequencies" not in where:
        from .config import repo_root
        from .protocols import load_protocol

        f, a = sweep_points(load_protocol(repo_root() / "conf" / "test" / "topmount.yaml"))
        where.setdefault("frequencies", f)
        where.setdefault("amplitude", a)
    return top_mount_report(d, best, ci, None, where["frequencies"], float(where.get("amplitude", 1e-4)))


def _documented_force_chain(cfg: dict, protocol_file: str) -> dict:
    """Nominal values of the force chain's nuisance keys: the load cell's
    bandwidth [Hz] (``force_bandwidth`` of the search config, else the
    repository's documented bench, conf/test/<protocol_file> ``sensors.force``)
    with no extra delay [s] and a zero offset [N] of 0 (a tared bench)."""
    bw = cfg.get("force_bandwidth")
    if bw is None:
        try:
            from .config import repo_root
            from .protocols import ProtocolError, load_protocol

            bw = load_protocol(repo_root() / "conf" / "test" / protocol_file).get("sensors", {}).get("force")
        except (FileNotFoundError, OSError, ProtocolError):
            bw = None
    from .calibration.approach1 import _force_chain_nominal

    return _force_chain_nominal(None if bw is None else float(bw))


def _specs(d: Design, items, prefix: str, where: str, nuisance: dict | None = None):
    from .calibration.approach1 import specs_from_config

    try:
        return specs_from_config(d, list(items), prefix=prefix, where=where, nuisance=nuisance)
    except ValueError as e:
        raise FitError(str(e)) from None


def _study_doc(fname: str) -> dict:
    """The study's calibration config conf/calibration/<fname>."""
    from .config import repo_root

    try:
        p = repo_root() / "conf" / "calibration" / fname
    except FileNotFoundError:
        raise FitError("no --bounds / --param given and no conf/calibration/ here for a default search space") \
            from None
    return yaml_load(p.read_text())


def _study_items(fname: str, section: str) -> list:
    """The study's search space (conf/calibration/<fname>) as the default."""
    return _study_doc(fname)[section]


__all__ = ["FitError", "lugre_force", "simulate_friction", "record_velocity", "fit_friction", "fit_valve",
           "fit_compliance", "fit_topmount", "coulomb_viscous_fit", "nrmse", "gauss_newton_ci"]
