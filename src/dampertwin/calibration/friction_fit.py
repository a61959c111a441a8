"""The friction-submodel fit (``dampertwin fit friction``) on a friction-device
record (time, displacement, force, optional velocity; force positive
opposing positive velocity).

- model: LuGre with Stribeck curve (thesis eq. 4.38-4.41) in the
  friction-only configuration (:mod:`dampertwin.model.friction_only`), with
  the library's asymmetric friction and free play on request;
- records split by cycles: the last ``holdout_cycles`` cycles of the fitted
  record are never fitted, their NRMSE is reported (``nrmse_held_out``);
  the simulation runs through the whole record (the state is continuous),
  only the residuals of the fitted cycles enter the objective;
- search space derived from the record's magnitudes (force range, stroke,
  velocity, sampling interval), never from the damper's design. A parameter
  ending on a data-derived bound has that bound widened and is refitted
  (:data:`WIDEN_ROUNDS` times); a parameter still on a bound, or on a
  physical / user bound, is listed in ``bound_hits`` and ``flags``;
- optimiser: multi-start bounded least squares (the core's
  :func:`~.optimisers.run` with ``LeastSquaresSettings``: scipy,
  Latin-hypercube starts in the unit box of the parameter spec);
- effects: with effects requested, the fit without each of them is also
  run, and an effect is *supported* when dropping it raises the held-out
  NRMSE by more than :data:`SUPPORT_GAIN` (relative).

NRMSE = RMS(simulated - measured) / (max - min of measured) over the
samples of the cycles in question.
"""

from __future__ import annotations

import numpy as np

from .ga import FitError, ParamSpec
from .ga import bound_hits as _bound_hits
from ..model.friction_only import simulate_friction

FRICTION_PARAMS = ("F_c", "F_s", "k_b", "s2", "c_comp", "vd", "a_s", "alpha_s")
EFFECT_PARAMS = {"asymmetric": "a", "free_play": "delta"}  # effect -> its fitted parameter
EFFECTS = tuple(EFFECT_PARAMS)
ALL_PARAMS = FRICTION_PARAMS + ("a", "v_reg", "delta")
FRICTION_KEYS = {"F_c": "rod_friction.F_c", "F_s": "rod_friction.F_s", "k_b": "rod_friction.k_b",
                 "s2": "constants.s2", "c_comp": "constants.c_comp", "vd": "constants.vd",
                 "a_s": "constants.a_s", "alpha_s": "constants.alpha_s",
                 "v_reg": "rod_friction_asymmetric.v_reg"}
A_LIMIT = 0.9  # |a| < 1 keeps both directions' friction positive (model limit of the direction factor)
BOUND_TOL = 1e-3  # a value within this fraction of its search interval from an end is "on the bound"
WIDEN_ROUNDS = 3  # refits after widening a data-derived bound the optimum sits on
WIDEN_LOG = 100.0  # a log-scale bound moves by this factor per round
WIDEN_LIN = 2.0  # a linear bound moves by this many interval widths per round
SUPPORT_GAIN = 0.05  # held-out NRMSE rise (relative) without an effect that counts as support
HYST = 0.05  # displacement hysteresis of a cycle boundary, fraction of the stroke


FrictionFitError = FitError  # the project's one fit error (calibration.ga)


# ---------------------------------------------------------------- records

def record_velocity(t: np.ndarray, displacement: np.ndarray | None, velocity: np.ndarray | None) -> np.ndarray:
    """Sliding velocity [m/s]: the measured one if given, else the
    displacement differentiated (central differences)."""
    if velocity is not None:
        return np.asarray(velocity, float)
    if displacement is None:
        raise FrictionFitError("record has neither 'velocity [m/s]' nor 'displacement [m]'")
    return np.gradient(np.asarray(displacement, float), np.asarray(t, float))


def cycle_index(x: np.ndarray) -> np.ndarray:
    """Cycle number of every sample: a new cycle starts where the
    displacement crosses its mid-stroke upwards, after having been below it
    by more than :data:`HYST` of the stroke (noise does not split cycles).
    Samples before the first crossing are cycle 0."""
    x = np.asarray(x, float)
    mid, band = 0.5 * (x.max() + x.min()), HYST * np.ptp(x)
    idx = np.zeros(len(x), int)
    armed, c = False, 0
    for i in range(len(x)):  # one pass over the record, at load time only
        if x[i] < mid - band:
            armed = True
        elif armed and x[i] >= mid:
            armed, c = False, c + 1
        idx[i] = c
    return idx


def split_cycles(x: np.ndarray | None, n: int, holdout: int | None) -> tuple[np.ndarray, dict]:
    """Mask of fitted samples and a description. ``holdout``: cycles at the
    end held out (None: a third of the cycles when there are 3 or more)."""
    if x is None or np.ptp(x) == 0:
        if holdout:
            raise FrictionFitError("held-out cycles need a 'displacement [m]' column to find the cycles")
        return np.ones(n, bool), {"cycles": 1, "fitted": [0], "held_out": []}
    idx = cycle_index(x)
    nc = int(idx[-1]) + 1
    k = (nc // 3 if nc >= 3 else 0) if holdout is None else int(holdout)
    if not 0 <= k < nc:
        raise FrictionFitError(f"--holdout-cycles {k}: the record has {nc} cycles; expected 0 .. {nc - 1}")
    fitted = idx < nc - k
    return fitted, {"cycles": nc, "fitted": list(range(nc - k)), "held_out": list(range(nc - k, nc))}


# ---------------------------------------------------------------- search space

def data_bounds(F: np.ndarray, x: np.ndarray | None, v: np.ndarray, dt: float, effects=()) -> list[dict]:
    """Default search items from the record (``origin: data``): force levels
    up to twice the largest force; bristle stiffness from the force built
    over the whole stroke (lowest) to that built within a tenth of one
    sample's travel at top speed (highest); viscous coefficient up to twice
    the largest force at top speed; free play up to a quarter stroke."""
    fmax = float(np.max(np.abs(F))) or 1.0
    vmax = float(np.max(np.abs(v))) or 1.0
    stroke = float(np.ptp(x)) if x is not None and np.ptp(x) > 0 else vmax * dt * len(F)
    items = [{"name": "F_c", "bounds": [0.0, 1.5 * fmax]}, {"name": "F_s", "bounds": [0.0, 2.0 * fmax]},
             {"name": "k_b", "bounds": [fmax / stroke, fmax / (0.1 * vmax * dt)], "scale": "log"},
             {"name": "s2", "bounds": [0.0, 2.0 * fmax / vmax]}]
    if "asymmetric" in effects:
        items.append({"name": "a", "bounds": [-A_LIMIT, A_LIMIT]})
    if "free_play" in effects:
        items.append({"name": "delta", "bounds": [0.0, 0.25 * stroke]})
    return [{**it, "origin": "data"} for it in items]


# ends that are limits of the physics or the model, never widened: zero force / viscosity / play, |a| < 1
PHYSICAL_ENDS = {("F_c", 0), ("F_s", 0), ("s2", 0), ("delta", 0), ("a", 0), ("a", 1)}


# the physical range of each parameter (low, high, low included, what it is): a user bound outside it is refused
PHYSICAL_RANGE = {"F_c": (0.0, None, True, "Coulomb friction force [N]"),
                  "F_s": (0.0, None, True, "static friction force [N]"),
                  "k_b": (0.0, None, False, "bristle stiffness [N/m]"),
                  "s2": (0.0, None, True, "viscous coefficient [N*s/m]"),
                  "c_comp": (0.0, None, True, "bristle damping [N*s/m]"),
                  "vd": (0.0, None, False, "damping velocity [m/s]"),
                  "a_s": (0.0, None, False, "Stribeck velocity [m/s]"),
                  "alpha_s": (0.0, None, False, "Stribeck exponent [-]"),
                  "a": (-1.0, 1.0, False, "direction factor [-]"),
                  "v_reg": (0.0, None, False, "switching velocity [m/s]"),
                  "delta": (0.0, None, True, "free play [m]")}


# fixed values that must exceed their range's closed end: LuGre's steady bristle state z_ss = v / g(v) with
# g(0) = F_s (eq. 4.38-4.41) divides by a fixed F_s = 0; a search's bound at 0 is never an iterate (trf stays
# strictly inside its bounds)
FIXED_OPEN = {"F_s"}


def _finite(x) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_)) \
        and bool(np.isfinite(x))


def _item_interval(it: dict, label: str) -> tuple[float, float, str]:
    """An item's (low, high, scale), checked for shape, scale and the
    parameter's physical range; ``label``: 'WHERE: item I (NAME)'."""
    nm, b, scale = label.rsplit("(", 1)[1].rstrip(")"), it["bounds"], it.get("scale", "lin")
    if not (isinstance(b, (list, tuple)) and len(b) == 2 and all(map(_finite, b)) and b[0] < b[1]):
        raise FrictionFitError(f"{label}: bad interval {b!r}; expected [low, high], two finite numbers, low < high")
    lo, hi = float(b[0]), float(b[1])
    if scale not in ("lin", "log"):
        raise FrictionFitError(f"{label}: scale {scale!r}; expected lin or log")
    if scale == "log" and lo <= 0:
        raise FrictionFitError(f"{label}: bad interval [{lo:g}, {hi:g}] for scale log; expected 0 < low < high")
    pl, ph, closed, what = PHYSICAL_RANGE[nm]
    if (lo < pl if closed else lo <= pl) or (ph is not None and hi >= ph):
        rng = f"{'[' if closed else '('}{pl:g}, {'inf' if ph is None else f'{ph:g}'})"
        raise FrictionFitError(f"{label}: bounds [{lo:g}, {hi:g}] outside the physical range of {nm}, the {what}: "
                               f"expected within {rng}")
    return lo, hi, scale


def specs_of(items: list, where: str) -> tuple[list[ParamSpec], list[str]]:
    """Parameter specs and each one's origin ('data' or 'user'); a bad item
    is a FrictionFitError naming ``where``, the item and what was expected."""
    specs, origin = [], []
    for i, it in enumerate(items):
        nm = it.get("name", it.get("key")) if isinstance(it, dict) else None
        nm = nm.split(".")[-1] if isinstance(nm, str) else nm
        if nm not in ALL_PARAMS:
            raise FrictionFitError(f"{where}: item {i} ({it!r}): unknown friction parameter; expected one of "
                                   f"{', '.join(ALL_PARAMS)}")
        if "bounds" not in it:
            raise FrictionFitError(f"{where}: item {i} ({nm}): friction fits need absolute 'bounds: [lo, hi]'")
        lo, hi, scale = _item_interval(it, f"{where}: item {i} ({nm})")
        specs.append(ParamSpec(nm, lo, hi, scale))
        origin.append(it.get("origin", "user"))
    return specs, origin


def _widened(s: ParamSpec, end: int) -> ParamSpec:
    if s.scale == "log":
        return ParamSpec(s.key, s.lo / WIDEN_LOG, s.hi, "log") if end == 0 else \
            ParamSpec(s.key, s.lo, s.hi * WIDEN_LOG, "log")
    w = WIDEN_LIN * (s.hi - s.lo)
    return ParamSpec(s.key, s.lo - w, s.hi, "lin") if end == 0 else ParamSpec(s.key, s.lo, s.hi + w, "lin")


def bound_hits(specs: list[ParamSpec], g: np.ndarray, origin: list[str]) -> list[dict]:
    """Parameters within :data:`BOUND_TOL` of an end of their interval, the
    bound's kind physical / data-derived / user."""
    def kind(i, end):
        return "physical" if (specs[i].key, end) in PHYSICAL_ENDS else ("data-derived" if origin[i] == "data" else "user")

    return _bound_hits(specs, {s.key: float(s.to_value(gi)) for s, gi in zip(specs, g)}, tol=BOUND_TOL, kind=kind)


# ---------------------------------------------------------------- optimiser

def fit_model(t, v, F, fitted, base: dict, specs: list[ParamSpec], origin: list[str], *, seed: int = 0,
              starts: int = 8) -> dict:
    """Fit ``specs`` on the ``fitted`` samples, widening data-derived bounds
    the optimum sits on. Returns values, final specs, bound hits, cost,
    rounds."""
    from .optimisers import LeastSquaresSettings, run
    from .polish import Records

    specs = list(specs)
    extra: list = []
    for rnd in range(WIDEN_ROUNDS + 1):
        keys = [s.key for s in specs]

        def residuals(X, keys=keys):
            """Force residual [N] on the fitted samples of each parameter row."""
            return np.array([(simulate_friction(t, v, **{**base, **dict(zip(keys, map(float, row)))}) - F)[fitted]
                             for row in np.atleast_2d(X)])

        try:
            res = run(Records(residuals, np.ones(int(np.sum(fitted)))), specs, LeastSquaresSettings(starts),
                      seed=seed + rnd, extra=extra)
        except ValueError as e:  # scipy: "Residuals are not finite in the initial point"
            if "not finite" not in str(e):
                raise
            raise FrictionFitError(f"the friction model gives no finite force at a start inside the bounds "
                                   f"{ {sp.key: [sp.lo, sp.hi] for sp in specs} } with fixed {base}; expected "
                                   f"values the LuGre law can run (F_s > 0, k_b > 0, eq. 4.38-4.41)") from None
        genes = res.top[0]
        hits = bound_hits(specs, genes, origin)
        movable = [h for h in hits if h["kind"] == "data-derived"]
        if not movable or rnd == WIDEN_ROUNDS:
            break
        values = {**base, **res.best}
        for h in movable:
            j = keys.index(h["parameter"])
            specs[j] = _widened(specs[j], 0 if h["bound"] == "lower" else 1)
        extra = [np.array([s.to_gene(values[s.key]) for s in specs])]  # restart from the optimum too
    return {"values": {**base, **res.best}, "specs": specs, "genes": genes, "bound_hits": hits,
            "cost": res.best_objective, "widening_rounds": rnd}


def nrmse(measured: np.ndarray, simulated: np.ndarray) -> float:
    """RMS error normalised by the measured range (max - min)."""
    m, s = np.asarray(measured, float), np.asarray(simulated, float)
    rng = float(np.ptp(m)) if len(m) else 0.0
    if not np.all(np.isfinite(s)) or rng == 0:
        return float("nan")
    return float(np.sqrt(np.mean((s - m) ** 2)) / rng)


def coulomb_viscous_fit(v: np.ndarray, F: np.ndarray) -> dict:
    """Baseline F = F_c sign(v) + c v by linear least squares."""
    A = np.column_stack([np.sign(v), v])
    (fc, c), *_ = np.linalg.lstsq(A, F, rcond=None)
    return {"F_c": float(fc), "c": float(c)}


def coulomb_viscous(v: np.ndarray, cv: dict) -> np.ndarray:
    return np.column_stack([np.sign(v), v]) @ [cv["F_c"], cv["c"]]


# ---------------------------------------------------------------- the fit

def _jacobian(t, v, F, fitted, values: dict, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Residual and its Jacobian in physical units (central differences,
    steps 1e-4 relative) on the fitted samples."""
    r0 = (simulate_friction(t, v, **values) - F)[fitted]
    J = np.empty((len(r0), len(names)))
    for j, k in enumerate(names):
        h = 1e-4 * max(abs(values[k]), 1e-12)
        up, dn = dict(values), dict(values)
        up[k] += h
        dn[k] -= h
        J[:, j] = (simulate_friction(t, v, **up) - simulate_friction(t, v, **dn))[fitted] / (2 * h)
    return r0, J


def _flag(h: dict) -> str:
    what = {"data-derived": "a bound derived from the record, still reached after widening it "
                            f"{WIDEN_ROUNDS} times", "user": "the bound given by the user",
            "physical": "a physical limit of the model"}[h["kind"]]
    return (f"{h['parameter']} = {h['value']:.6g} ended on its {h['bound']} bound {h['limit']:.6g} ({what}): "
            f"the optimum may lie beyond it")


def fit_friction_record(rec: dict, base: dict, *, items: list | None = None, effects=(), holdout: int | None = None,
                        predicted=(), seed: int = 0, starts: int = 8, where: str = "friction search space",
                        fixed=()) -> dict:
    """Fit the friction law to one record ``rec`` (arrays ``t`` [s], ``v``
    [m/s], ``F`` [N], optional ``x`` [m]); ``predicted``: further records
    only simulated. ``base``: values of every parameter not searched;
    ``fixed``: names the default search (from the record) leaves out, held at ``base``.
    Returns the report (``parameters``, ``bound_hits``, ``flags``, NRMSE of
    fitted / held-out cycles, ``effects`` support, ``uncertainty``) and,
    under ``_sims``, the simulated forces for plots."""
    from .uncertainty import gauss_newton_ci

    bad = [e for e in effects if e not in EFFECTS]
    if bad:
        raise FrictionFitError(f"unknown friction effect(s) {bad}; expected {', '.join(EFFECTS)}")
    t, v, F, x = rec["t"], rec["v"], rec["F"], rec.get("x")
    fitted, cycles = split_cycles(x, len(t), holdout)
    held = ~fitted
    dt = float(np.mean(np.diff(t)))
    auto = data_bounds(F[fitted], None if x is None else x[fitted], v[fitted], dt, effects)
    items = list(items) if items else [i for i in auto if i["name"] not in EFFECT_PARAMS.values()
                                       and i["name"] not in fixed]
    names_given = {(i.get("name") or i.get("key", "")).split(".")[-1] for i in items}
    items += [i for i in auto if i["name"] in [EFFECT_PARAMS[e] for e in effects] and i["name"] not in names_given]
    specs, origin = specs_of(items, where)
    base = {**base, "a": 0.0, "delta": 0.0, **{k: base[k] for k in ("a", "delta") if k in base}}

    def run(drop=()):
        keep = [j for j, s in enumerate(specs) if s.key not in drop]
        b = {**base, **{p: 0.0 for p in drop}}
        return fit_model(t, v, F, fitted, b, [specs[j] for j in keep], [origin[j] for j in keep], seed=seed,
                         starts=starts)

    main = run()
    p = main["values"]
    names = [s.key for s in main["specs"]]
    sim = simulate_friction(t, v, **p)
    score = {"fitted": nrmse(F[fitted], sim[fitted]), "held_out": nrmse(F[held], sim[held]) if held.any() else None}
    support = {}
    if effects:
        variants = {e: run(drop=(EFFECT_PARAMS[e],)) for e in effects}
        if len(effects) > 1:
            variants["none"] = run(drop=tuple(EFFECT_PARAMS[e] for e in effects))
        for e, fit_e in variants.items():
            s_e = simulate_friction(t, v, **fit_e["values"])
            row = {"nrmse_fitted_without": nrmse(F[fitted], s_e[fitted]),
                   "nrmse_held_out_without": nrmse(F[held], s_e[held]) if held.any() else None}
            if e != "none":
                row[EFFECT_PARAMS[e]] = p[EFFECT_PARAMS[e]]
                ref = row["nrmse_held_out_without"] if held.any() else row["nrmse_fitted_without"]
                now = score["held_out"] if held.any() else score["fitted"]
                row["supported"] = bool(ref > (1 + SUPPORT_GAIN) * now)
                row["judged_on"] = "held-out cycles" if held.any() else "fitted cycles (no held-out cycles)"
            support["without " + e if e != "none" else "without any effect"] = row
    r0, J = _jacobian(t, v, F, fitted, p, names)
    ci = gauss_newton_ci(J, r0, names, np.array([p[k] for k in names]))
    cv = coulomb_viscous_fit(v[fitted], F[fitted])
    cv_sim = coulomb_viscous(v, cv)
    flags = [_flag(h) for h in main["bound_hits"]]
    flags += [f"effect {e} not supported by the held-out cycles (held-out NRMSE without it "
              f"{support['without ' + e]['nrmse_held_out_without']:.4f} vs {score['held_out']:.4f} with it)"
              for e in effects if held.any() and not support["without " + e]["supported"]]
    preds = []
    for q in predicted:
        s_q = simulate_friction(q["t"], q["v"], **p)
        preds.append({"nrmse": nrmse(q["F"], s_q), "nrmse_coulomb_viscous": nrmse(q["F"], coulomb_viscous(q["v"], cv)),
                      "samples": len(q["F"]), "_sim": s_q})
    model = "LuGre with Stribeck curve, thesis eq. 4.38-4.41 (errata 34)" + "".join(
        {"asymmetric": " + asymmetric friction (Olsson et al. 1998, 3.6)",
         "free_play": " + free play (dead zone, Nordin & Gutman 2002)"}[e] for e in effects)
    return {"submodel": "friction", "model": model, "effects_requested": list(effects),
            "objective": {"name": "sum of squared force residuals on the fitted cycles / 2 [N^2]",
                          "value": main["cost"]},
            "parameters": {k: p[k] for k in names},
            "fixed": {k: p[k] for k in ALL_PARAMS if k not in names and k in p},
            "bounds": {s.key: [s.lo, s.hi, s.scale] for s in main["specs"]},
            "bounds_origin": {s.key: o for s, o in zip(specs, origin)},
            "widening_rounds": main["widening_rounds"], "bound_hits": main["bound_hits"], "flags": flags,
            "cycles": cycles, "nrmse": score["fitted"], "nrmse_held_out": score["held_out"],
            "nrmse_all": nrmse(F, sim), "effects": support, "uncertainty": ci,
            "baseline": {"model": "F = F_c sign(v) + c v (linear least squares on the fitted cycles)",
                         "F_c [N]": cv["F_c"], "c [N*s/m]": cv["c"], "nrmse": nrmse(F[fitted], cv_sim[fitted]),
                         "nrmse_held_out": nrmse(F[held], cv_sim[held]) if held.any() else None},
            "optimizer": f"scipy least_squares, {starts} Latin-hypercube starts per round, seed {seed}",
            "_sims": {"fitted": sim, "mask": fitted, "coulomb_viscous": cv_sim, "predicted": preds}}
