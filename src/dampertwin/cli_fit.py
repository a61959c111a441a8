"""``dampertwin fit``: the command line's options (search spaces from
``--bounds`` / ``--param``, profile budgets, the friction options) to the
fits on files of :mod:`dampertwin.cli_fit_files`; the CLI layer, above the
calibration core."""

from __future__ import annotations

import math
import os
from pathlib import Path

from .design import yaml_load
from .calibration.ga import FitError
from .cli_fit_files import (fit_active_valve, fit_compliance, fit_damper, fit_friction, fit_outputs, fit_topmount,
                            fit_valve)


def parse_param_args(items: list[str]) -> list[dict]:
    """``name=lo:hi[:log]`` strings -> search-space items (absolute bounds)."""
    out = []
    for s in items:
        try:
            name, rng = s.split("=", 1)
            parts = rng.split(":")
            lo, hi = float(parts[0]), float(parts[1])
            scale = parts[2] if len(parts) > 2 else "lin"
        except (ValueError, IndexError):
            raise FitError(f"--param {s!r}: expected name=lo:hi or name=lo:hi:log") from None
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise FitError(f"--param {s!r}: the bounds must be finite numbers")
        if scale not in ("lin", "log") or len(parts) > 3:
            raise FitError(f"--param {s!r}: scale {':'.join(parts[2:])!r}; expected name=lo:hi, name=lo:hi:lin or "
                           f"name=lo:hi:log")
        key = "key" if "." in name else "name"
        out.append({key: name.strip(), "bounds": [lo, hi], "scale": scale})
    return out


# what a --bounds file may say, per fit (docs/how-to/fit-submodel.md); anything else is a typo, refused
BOUNDS_KEYS = {
    "valve": {"parameters", "valve", "objective", "bench", "input_cutoff", "ga", "polish"},
    "compliance": {"parameters", "input_cutoff", "force_bandwidth", "ga", "polish"},
    "topmount": {"parameters", "input_cutoff", "force_bandwidth", "ga", "polish", "static", "runs", "dynamic_run",
                 "determined"},
    "friction": {"parameters", "fixed"},
    "damper": {"parameters", "input_cutoff", "ga", "polish"},
}
BENCH_KEYS = {"bench_volume", "bench_back_pressure"}


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def check_search_config(doc: dict, where: str, submodel: str) -> None:
    """The --bounds file's keys and the types a fit cannot check before its
    first simulation: FitError naming the file and the key."""
    from .calibration.approach1 import ITEM_KEYS
    from .calibration.friction_fit import FIXED_OPEN, FRICTION_KEYS, PHYSICAL_RANGE

    allowed = BOUNDS_KEYS.get(submodel, set())
    extra = sorted(map(str, set(doc) - allowed))
    if extra:
        raise FitError(f"{where}: unknown key(s) {', '.join(extra)} for a {submodel} fit; expected "
                       f"{', '.join(sorted(allowed))}")
    items = doc.get("parameters")
    if "parameters" in doc:
        if not isinstance(items, list) or not items:
            raise FitError(f"{where}: parameters: expected a non-empty list of items (name or key, bounds or "
                           f"window, scale), got {items!r}")
        for i, it in enumerate(items):
            if not isinstance(it, dict) or set(it) - ITEM_KEYS:
                raise FitError(f"{where}: parameters item {i} ({it!r}): expected a mapping of "
                               f"{', '.join(sorted(ITEM_KEYS))}")
        names = [it.get("key", it.get("name")) for it in items]
        dup = sorted({str(n) for n in names if names.count(n) > 1})
        if dup:
            raise FitError(f"{where}: parameters: {', '.join(dup)} listed more than once")
    fixed = doc.get("fixed")
    if "fixed" in doc:
        if not isinstance(fixed, dict):
            raise FitError(f"{where}: fixed: expected a mapping name: value, got {fixed!r}")
        for k, v in fixed.items():
            if k not in FRICTION_KEYS:
                raise FitError(f"{where}: fixed: unknown friction parameter {k!r}; expected one of "
                               f"{', '.join(FRICTION_KEYS)}")
            if not _number(v):
                raise FitError(f"{where}: fixed: {k} = {v!r}; expected a finite number")
            if k in PHYSICAL_RANGE:
                lo, hi, closed, what = PHYSICAL_RANGE[k]
                closed = closed and k not in FIXED_OPEN
                if (v < lo if closed else v <= lo) or (hi is not None and v >= hi):
                    raise FitError(f"{where}: fixed: {k} = {v!r} outside the physical range of the {what}: expected "
                                   f"{'>=' if closed else '>'} {lo:g}" + ("" if hi is None else f" and < {hi:g}"))
        searched = {str(n).split(".")[-1] for n in [it.get("key", it.get("name")) for it in items or []]}
        both = sorted(searched & set(fixed))
        if both:
            raise FitError(f"{where}: {', '.join(both)} both fixed and searched; give each in one place")
    for key in ("input_cutoff", "force_bandwidth"):
        if key in doc and not (_number(doc[key]) and doc[key] > 0):
            raise FitError(f"{where}: {key}: expected a positive frequency in Hz, got {doc[key]!r}")
    for key in ("ga", "polish", "objective", "static", "determined"):
        if key in doc and not isinstance(doc[key], dict):
            raise FitError(f"{where}: {key}: expected a mapping, got {doc[key]!r}")
    if "polish" in doc:
        _check_polish(doc["polish"], where)
    if submodel == "topmount":
        _check_topmount_keys(doc, where)
    if "bench" in doc:
        b = doc["bench"]
        if not isinstance(b, dict) or set(b) - BENCH_KEYS or not all(_number(v) for v in b.values()) \
                or not b.get("bench_volume", 1.0) > 0 or not b.get("bench_back_pressure", 0.0) >= 0:
            raise FitError(f"{where}: bench: expected bench_volume [m^3] > 0 and bench_back_pressure [Pa] >= 0, "
                           f"got {b!r}")


def _positive(v, integer: bool = False) -> bool:
    return _number(v) and v > 0 and (not integer or float(v).is_integer())


def _check_polish(pol: dict, where: str) -> None:
    """polish: {starts, max_nfev[, step, min_distance]} (calibration.polish.POLISH_KEYS)."""
    from .calibration.polish import POLISH_KEYS

    bad = sorted(map(str, set(pol) - set(POLISH_KEYS)))
    if bad or not {"starts", "max_nfev"} <= set(pol):
        raise FitError(f"{where}: polish: {pol!r}; expected starts and max_nfev (and optional step, "
                       f"min_distance), not {', '.join(bad) or 'fewer'}")
    for k, v in pol.items():
        if not _positive(v, integer=k in ("starts", "max_nfev")):
            raise FitError(f"{where}: polish: {k} = {v!r}; expected a positive "
                           f"{'integer' if k in ('starts', 'max_nfev') else 'number'}")


def _check_topmount_keys(doc: dict, where: str) -> None:
    """A top-mount fit's static / runs / dynamic_run / determined keys (fit_topmount's docstring)."""
    st = doc.get("static")
    if st is not None:
        if set(st) - {"run", "order", "input_cutoff"} or not isinstance(st.get("run"), str):
            raise FitError(f"{where}: static: {st!r}; expected {{run: LABEL, order: 1..5, input_cutoff: Hz}}")
        if "order" in st and not (isinstance(st["order"], int) and not isinstance(st["order"], bool)
                                  and 1 <= st["order"] <= 5):
            raise FitError(f"{where}: static.order: {st['order']!r}; expected an integer 1..5 (thesis 7.2: 5)")
        if "input_cutoff" in st and not _positive(st["input_cutoff"]):
            raise FitError(f"{where}: static.input_cutoff: {st['input_cutoff']!r}; expected a positive frequency in Hz")
    runs = doc.get("runs")
    if "runs" in doc and not (isinstance(runs, list) and runs and all(isinstance(r, str) and r for r in runs)):
        raise FitError(f"{where}: runs: {runs!r}; expected a list of run labels (e.g. [sweep_A0.001_f10])")
    if "dynamic_run" in doc and not (isinstance(doc["dynamic_run"], str) and doc["dynamic_run"]):
        raise FitError(f"{where}: dynamic_run: {doc['dynamic_run']!r}; expected a run label")
    det = doc.get("determined")
    if det is not None:
        f = det.get("frequencies", [1.0])  # absent: the documented sweep's (conf/test/topmount.yaml)
        if set(det) - {"frequencies", "amplitude"} or not (isinstance(f, list) and f and all(_positive(x) for x in f)) \
                or not _positive(det.get("amplitude", 1.0)) or ("frequencies" in det and "amplitude" not in det):
            raise FitError(f"{where}: determined: {det!r}; expected {{frequencies: [Hz > 0, ...], amplitude: m > 0}}")


def load_search_config(path: str | os.PathLike | None, submodel: str | None = None) -> dict:
    """The --bounds file (a mapping), checked for a ``submodel`` fit when given."""
    if path is None:
        return {}
    p = Path(path)
    if not p.is_file():
        raise FitError(f"{p}: bounds file not found")
    doc = yaml_load(p.read_text())
    if not isinstance(doc, dict):
        raise FitError(f"{p}: expected a mapping with a 'parameters:' list")
    if submodel is not None:
        check_search_config(doc, str(p), submodel)
    return doc


def _merge_items(cfg_items: list | None, cli_items: list[dict], prefix: str = "") -> list:
    """Command-line items replace config items of the same parameter: keys compared after resolving a
    name within the fit's group (``prefix``, e.g. ``piston_intake.``: ``a`` is ``piston_intake.a``)."""
    def key(it):
        return str(it["key"]) if "key" in it else prefix + str(it.get("name")) if isinstance(it, dict) else None

    cli = {key(i) for i in cli_items}
    return [i for i in (cfg_items or []) if not isinstance(i, dict) or key(i) not in cli] + cli_items


# ---------------------------------------------------------------- statistics

def _profile(name: str) -> dict:
    """GA and polish budgets of a study profile (conf/profile/<name>.yaml)."""
    from .config import repo_root

    try:
        p = repo_root() / "conf" / "profile" / f"{name}.yaml"
    except FileNotFoundError:
        raise FitError(f"--profile {name}: no conf/profile/ here (run inside the repository)") from None
    if not p.is_file():
        raise FitError(f"--profile {name}: {p} not found")
    return yaml_load(p.read_text())


def _items_source(cfg: dict, params) -> str:
    """Where the search items came from (the --bounds file, --param), for their errors."""
    src = [cfg["_where"] if cfg.get("parameters") and cfg.get("_where") else None, "--param" if params else None]
    return " + ".join(x for x in src if x) or "friction search space"


# options of the searched fits; an active-valve map is read off its record (no search, no budget, no seed)
SEARCH_OPTIONS = {"predict": [], "bounds": None, "param": [], "valve": None, "current": None, "population": None,
                  "generations": None, "seed": 0, "profile": None, "scheduler": None, "effect": [],
                  "holdout_cycles": None}


def _fit_active_valve(args) -> list[str]:
    """``dampertwin fit active-valve``: refuses the search options, returns the map's flags."""
    given = [k for k, default in SEARCH_OPTIONS.items() if getattr(args, k, default) != default]
    if given:
        raise FitError(f"{', '.join('--' + k.replace('_', '-') for k in given)}: an active-valve map is read off its "
                       f"bench record on the design's grid (no search); give --data, --design and --out only")
    return list(fit_active_valve(args.data, design=args.design, out=args.out)["flags"])


def run_fit_cli(args) -> tuple[Path, list[str]]:
    """``dampertwin fit`` entry: returns the written fit.json path and the
    fit's flags (parameters on a bound, unsupported effects)."""
    from .io import check_targets

    data = [p for p in args.data.split(",") if p] if args.submodel == "damper" else [args.data]
    check_targets(fit_outputs(args.submodel, args.out, [*data, *(args.predict or [])]), "--out")  # before any work
    if args.submodel == "active-valve":
        return Path(args.out) / "fit.json", _fit_active_valve(args)
    cfg = load_search_config(args.bounds, args.submodel)
    if args.bounds:
        cfg["_where"] = str(args.bounds)
        if "ga" in cfg:
            cfg["_ga_where"] = str(args.bounds)
    if getattr(args, "profile", None):
        if args.submodel == "friction":
            raise FitError("--profile sets GA and polish budgets: valve, compliance and topmount fits only")
        prof = _profile(args.profile)
        section = {"valve": "valves"}.get(args.submodel, args.submodel)
        if section not in prof["ga"]:
            raise FitError(f"--profile {args.profile}: the profile has no GA budget for a {args.submodel} fit; "
                           f"give --population / --generations")
        if "ga" not in cfg:
            cfg["ga"], cfg["_ga_where"] = prof["ga"][section], f"--profile {args.profile}"
        cfg.setdefault("polish", prof.get("polish"))
    prefix = {"valve": f"{args.valve or cfg.get('valve')}.", "topmount": "top_mount."}.get(args.submodel, "")
    items = _merge_items(cfg.get("parameters"), parse_param_args(args.param), prefix) or None
    kw = dict(design=args.design, bounds=items, predict=args.predict, out=args.out, seed=args.seed)
    ga = dict(config=cfg, population=args.population, generations=args.generations,
              scheduler=getattr(args, "scheduler", None))
    if args.submodel != "friction" and (args.effect or args.holdout_cycles is not None):
        raise FitError("--effect and --holdout-cycles apply to friction fits only")
    if args.submodel == "friction" and ga["scheduler"]:
        raise FitError("--scheduler applies to the GA fits (valve, compliance, topmount); a friction fit is a "
                       "least-squares fit on this machine")
    if args.submodel == "friction":
        fixed = {k: float(v) for k, v in (cfg.get("fixed") or {}).items()}
        res = fit_friction(args.data, fixed=fixed, effects=tuple(dict.fromkeys(args.effect)),
                           holdout_cycles=args.holdout_cycles,
                           where=_items_source(cfg, args.param), **kw)
    elif args.submodel == "valve":
        valve = args.valve or cfg.get("valve")
        if not valve:
            raise FitError("a valve fit needs --valve (or 'valve:' in the bounds file)")
        res = fit_valve(args.data, valve, **kw, **ga)
    elif args.submodel == "damper":
        if args.current is not None:
            raise FitError("--current: a damper fit takes each record's current (a passive design reads none)")
        files = [p for p in args.data.split(",") if p]
        twice = sorted({p for p in files if [Path(q).resolve() for q in files].count(Path(p).resolve()) > 1})
        if twice:  # the same record twice would weigh it double without a word
            raise FitError(f"--data: {', '.join(twice)} given more than once; give each record once")
        res = fit_damper(files, **kw, **ga)
    elif args.submodel == "compliance":
        res = fit_compliance(args.data, current=args.current, **kw, **ga)
    else:
        res = fit_topmount(args.data, **kw, **ga)
    return Path(args.out) / "fit.json", list(res.get("flags", []))


__all__ = ["parse_param_args", "load_search_config", "run_fit_cli"]
