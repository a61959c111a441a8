"""``dampertwin fit`` on files: the command line's reading, defaults and
writing around the submodel fits of
:mod:`dampertwin.calibration.component_fits` (the CLI layer).

Each function reads its records through the project's one measurement
reader, takes default search spaces, budgets and benches from the
repository's conf/ (conf/calibration/, conf/test/, conf/design/baseline.yaml)
when not given, fits, adds each file's SHA-256 and, with ``out``, writes
``out/fit.json`` and the plots. Search bounds come from a config (YAML
``parameters:`` items, as in conf/calibration/) or ``name=lo:hi`` strings,
never from the damper's design bounds.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pandas as pd

from .calibration import component_fits as cf
from .calibration import friction_fit as _ff
from .calibration.ga import FitError
from .calibration.polish import PolishSettings
from .design import Design, load as load_design, yaml_load
from .fit_plots import friction_plots, series_plots
from .io import atomic_files, check_targets, json_safe


def _sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _write_json(path: Path, obj) -> Path:
    check_targets([path])
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(json_safe(obj), indent=2, sort_keys=False, default=float, allow_nan=False) + "\n"
    with atomic_files([path]) as (tmp,):
        tmp.write_text(text)
    return path


ACTIVE_VALVE_OUTPUTS = ("fit.json", "design.yaml", "map.csv", "pq.png")  # fit_active_valve's files in OUT


def fit_outputs(submodel: str, out, files) -> list[Path]:
    """The files a fit of ``submodel`` on ``files`` (fitted, then predicted) writes in ``out``: fit.json and a
    PNG per file (fit_plots: SUBMODEL_I_STEM.png), or the active-valve map's files."""
    out = Path(out)
    if submodel == "active-valve":
        return [out / n for n in ACTIVE_VALVE_OUTPUTS]
    return [out / "fit.json", *(out / f"{submodel}_{i}_{Path(f).stem}.png" for i, f in enumerate(files))]


def read_fit_record(path, protocol=None, valve=None) -> pd.DataFrame:
    """A record through the project's one measurement reader (protocol rate, duration, labels, magnitudes,
    dead channels, force sign; ``protocol`` None: the one its metadata names, else a generic device record)."""
    from .io import read_record

    return read_record(Path(path), protocol, valve=valve, require=("time", "force", "displacement|velocity"))[0]


def _read_all(paths, protocol=None, valve=None) -> list[pd.DataFrame]:
    """Every measurement file a fit reads, in one call (one reader)."""
    return [read_fit_record(p, protocol, valve=valve) for p in paths]


def _with_shas(result: dict, out, plots=None) -> dict:
    """Each file's SHA-256 in ``result['files']``; when ``out`` is given the
    plots (``plots(out)``) and then ``out/fit.json``, last: an earlier
    fit.json is removed first, so a run killed while plotting leaves no
    fit.json beside plots it does not describe."""
    for p, entry in result["files"].items():
        entry["sha256"] = _sha(Path(p))
    if out is not None:
        out = Path(out)
        check_targets([out / "fit.json"])  # a folder there: OutputError, nothing removed or written
        (out / "fit.json").unlink(missing_ok=True)
        out.mkdir(parents=True, exist_ok=True)
        if plots is not None:
            plots(out)
        _write_json(out / "fit.json", result)
    return result


def _repo_conf(*parts: str, instead: str) -> Path:
    """conf/<parts> of the repository around the working directory; a
    FitError saying what to give ``instead`` when there is none."""
    from .config import repo_root

    try:
        return repo_root().joinpath("conf", *parts)
    except FileNotFoundError:
        raise FitError(f"no {instead} given and no dampertwin repository here for conf/{'/'.join(parts)}") from None


def _default_design() -> Path:
    return _repo_conf("design", "baseline.yaml", instead="--design")


def _load(design) -> Design:
    return design if isinstance(design, Design) else load_design(design or _default_design())


def _study_doc(fname: str) -> dict:
    """The study's calibration config conf/calibration/<fname>."""
    return yaml_load(_repo_conf("calibration", fname, instead="--bounds / --param").read_text())


def _study_default(cfg: dict, key: str, fname: str, default):
    """``cfg[key]`` (the --bounds file's), else the study's conf/calibration/<fname> value (read only then:
    a --bounds file that gives the key needs no repository)."""
    if key in cfg:
        return cfg[key]
    return yaml_load(_repo_conf("calibration", fname, instead=f"{key} in --bounds").read_text()).get(key, default)


def _protocol(fname: str) -> dict | None:
    """conf/test/<fname>, None when absent."""
    from .protocols import load_protocol

    try:
        return load_protocol(_repo_conf("test", fname, instead="bench description"))
    except (FitError, FileNotFoundError):
        return None


def _flowbench_bench(cfg: dict) -> dict:
    """The flow bench's upstream volume [m^3] and back pressure [Pa]: the
    search config's ``bench:``, else the repository's documented bench
    (conf/test/flowbench.yaml), as the study's flow-bench stage uses."""
    if cfg.get("bench"):
        return dict(cfg["bench"])
    fb = _protocol("flowbench.yaml")
    return {} if fb is None else {"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]}


def _force_bandwidth(cfg: dict, protocol_file: str) -> float | None:
    """The load cell's bandwidth [Hz]: ``force_bandwidth`` of the search
    config, else the documented bench's (conf/test/<protocol_file> ``sensors.force``)."""
    bw = cfg.get("force_bandwidth")
    if bw is None:
        from .protocols import ProtocolError

        try:
            bw = (_protocol(protocol_file) or {}).get("sensors", {}).get("force")
        except (OSError, ProtocolError):
            bw = None
    return None if bw is None else float(bw)


def fit_valve(data, valve: str, *, design=None, bounds: list[dict] | None = None, predict=(), out=None,
              config: dict | None = None, seed: int = 0, population=None, generations=None, scheduler=None) -> dict:
    """Fit one valve on a flow-bench record file by the study's flow-bench fit
    (:func:`~dampertwin.calibration.component_fits.fit_valve_records`).
    Default search space: conf/calibration/valves.yaml's items for the valve
    kind, unless ``bounds`` / ``config['parameters']`` are given; GA and
    polish settings from ``config['ga']`` / ``config['polish']`` (a profile)."""
    d, cfg = _load(design), dict(config or {})
    kind = "shim" if valve in cf.SHIM_VALVES else "intake"
    items = bounds or cfg.get("parameters") or (_study_doc("valves.yaml")[kind] if valve in cf.VALVES else [])
    cutoff = float(_study_default(cfg, "input_cutoff", "valves.yaml", 20.0))
    if valve not in cf.VALVES:
        raise FitError(f"unknown valve {valve!r}; expected {', '.join(cf.VALVES)}")
    frames = _read_all([data, *predict], "flowbench", valve=valve)
    result, problem, sims = cf.fit_valve_records(
        d, valve, list(zip(map(str, [data, *predict]), frames)), items, cutoff=cutoff, bench=_flowbench_bench(cfg),
        settings=cf.ga_settings(cfg, population, generations),
        polish_settings=PolishSettings.from_config(cfg.get("polish") or cf.DEFAULT_POLISH), seed=seed,
        where=cfg.get("_where", "valve search space"), scheduler=scheduler,
        objective=_study_default(cfg, "objective", "valves.yaml", None))
    _with_shas(result, out, lambda o: series_plots(o, problem, sims, "dp [Pa]", "valve",
                     x_of=lambda t, ex, extra: (np.interp(t, ex.t0 + ex.dt * np.arange(len(ex.value)), ex.value)
                                                * 60000.0, "flow [l/min]")))
    return result


def _check_current(current: float, records) -> None:
    """--current [A] against each run's recorded current (when the record has one): a FitError naming the
    file and run where they differ by more than io.record.CURRENT_TOL."""
    from .io import runs
    from .io.record import CURRENT_TOL

    for path, df in records:
        if "current [A]" not in df.columns:
            continue
        for name, g in runs(df):
            i = float(np.mean(g["current [A]"].to_numpy()))
            if np.any(g["current [A]"].to_numpy() != 0) and abs(i - current) > CURRENT_TOL:  # zeros: none recorded
                raise FitError(f"{path}" + (f" run {name!r}" if name else "") + f": recorded at {i:.3g} A; --current "
                               f"{current:g} A would simulate it at another current (leave --current out: each "
                               f"run's own current is used)")


def fit_compliance(data, *, design=None, bounds=None, predict=(), out=None, config=None, seed=0,
                   current: float | None = None, population=None, generations=None, scheduler=None) -> dict:
    """Fit gas content and oil bulk modulus (default) on a damper-level sine
    record file (displacement input, force output, eq. 6.2)."""
    d, cfg = _load(design), dict(config or {})
    items = bounds or cfg.get("parameters") or _study_doc("compliance.yaml")["parameters"]
    frames = [read_fit_record(p, "compliance" if current is None else None) for p in [data, *predict]]
    if current is not None:  # --current stands in for a record without a current, never against its own
        _check_current(current, zip(map(str, [data, *predict]), frames))
    result, problem, sims = cf.fit_compliance_records(
        d, list(zip(map(str, [data, *predict]), frames)), items, cutoff=float(cfg.get("input_cutoff", 1000.0)),
        force_bandwidth=_force_bandwidth(cfg, "compliance.yaml"), settings=cf.ga_settings(cfg, population, generations),
        seed=seed, current=current, where=cfg.get("_where", "compliance search space"), scheduler=scheduler)
    _with_shas(result, out, lambda o: series_plots(o, problem, sims, "rod force [N]", "compliance"))
    return result


def fit_topmount(data, *, design=None, bounds=None, predict=(), out=None, config=None, seed=0,
                 population=None, generations=None, scheduler=None) -> dict:
    """Fit the top-mount parameters on a top-mount record file (displacement
    input, force output, eq. 6.3). ``config['static'] = {run, order}``: the
    static curve by least squares first; the GA uses ``config['runs']`` (or
    ``config['dynamic_run']``; default: all but the static); the dynamic
    stiffness is reported at ``config['determined']`` (default the
    documented sweep of conf/test/topmount.yaml, middle amplitude)."""
    from .calibration.identifiability import sweep_points

    d, cfg = _load(design), dict(config or {})
    items = bounds or cfg.get("parameters") or _study_doc("topmount.yaml")["parameters"]
    frames = [read_fit_record(p, "topmount") for p in [data, *predict]]
    where = dict(cfg.get("determined") or {})
    if "frequencies" not in where:
        proto = _protocol("topmount.yaml")
        if proto is None:
            raise FitError("no conf/test/topmount.yaml here for the dynamic-stiffness frequencies; give "
                           "'determined: {frequencies: [Hz, ...], amplitude: m}' in the bounds file")
        f, a = sweep_points(proto)
        where.setdefault("frequencies", f)
        where.setdefault("amplitude", a)
    result, problem, sims = cf.fit_topmount_records(
        d, list(zip(map(str, [data, *predict]), frames)), items, cutoff=float(cfg.get("input_cutoff", 500.0)),
        force_bandwidth=_force_bandwidth(cfg, "topmount.yaml"), settings=cf.ga_settings(cfg, population, generations),
        seed=seed, static=cfg.get("static"), want=cfg.get("runs") or ([cfg["dynamic_run"]] if cfg.get("dynamic_run")
                                                                       else None),
        where_k=where, where=cfg.get("_where", "top-mount search space"), scheduler=scheduler)
    _with_shas(result, out, lambda o: series_plots(o, problem, sims, "top mount force [N]", "topmount"))
    return result


def fit_friction(data, *, design: Design | str | os.PathLike | None = None, bounds: list[dict] | None = None,
                 predict=(), out: str | os.PathLike | None = None, seed: int = 0, starts: int = 8,
                 fixed: dict | None = None, effects=(), holdout_cycles: int | None = None,
                 velocity: str = "record", where: str = "friction search space") -> dict:
    """Fit the friction law (:mod:`dampertwin.calibration.friction_fit`) to a
    friction record file (``time [s]``, ``displacement [m]``, ``force [N]``,
    optional ``velocity [m/s]``; force positive opposing positive velocity).
    ``bounds``: search items (name + bounds [+ scale]); default from the
    record's magnitudes. Parameters not searched come from ``fixed``, then
    from ``design`` (default conf baseline values). ``effects``: library
    effects added to the law (asymmetric, free_play). ``holdout_cycles``:
    cycles at the end of the record not fitted (default a third).
    ``velocity``: 'record' (the velocity column if present) or
    'displacement' (always differentiate the displacement). ``where``: the
    search items' source (the --bounds file), named in their errors."""
    paths = [Path(data)] + [Path(p) for p in predict]
    frames = _read_all(paths)
    d = _load(design)
    base = {k: float(d[_ff.FRICTION_KEYS[k]]) for k in _ff.FRICTION_KEYS}
    base.update({k: float(v) for k, v in (fixed or {}).items()})
    result, recs, sims = cf.fit_friction_records([str(p) for p in paths], frames, base, items=bounds,
                                                 effects=effects, holdout=holdout_cycles, seed=seed, starts=starts,
                                                 velocity=velocity, fixed=tuple(fixed or ()), where=where)
    _with_shas(result, out, lambda o: friction_plots(o, paths, recs, sims, result))
    return result


def fit_damper(data, *, design=None, bounds=None, predict=(), out=None, config=None, seed=0, population=None,
               generations=None, scheduler=None) -> dict:
    """Fit the valves' and the gas's parameters on damper / dyno records (``data``: one path or a list, each
    simulated at the clicker setting its metadata names; calibration.damper_fit), predict ``predict``."""
    from .calibration.damper_fit import fit_damper_records
    from .io import read_record

    d, cfg = _load(design), dict(config or {})
    paths = [data] if isinstance(data, (str, os.PathLike)) else list(data)

    def read(p):
        frame, meta = read_record(Path(p), None, require=("time", "force", "displacement"))
        return str(p), frame, meta

    result, problem, sims = fit_damper_records(
        d, [read(p) for p in paths], [read(p) for p in predict], bounds or cfg.get("parameters"),
        settings=cf.ga_settings(cfg, population, generations), seed=seed,
        cutoff=float(cfg.get("input_cutoff", 1000.0)), where=cfg.get("_where", "damper search space"),
        scheduler=scheduler)
    _with_shas(result, out, lambda o: series_plots(o, problem, sims, "rod force [N]", "damper"))
    return result


def _design_with_map(d: Design, out: Path, record: str, sha: str) -> Path:
    """``out/design.yaml``: the design with no. 52 naming ``out/map.csv`` (its source line says how it was found)."""
    import yaml

    from .design import loads

    doc = yaml.safe_load(d.dumps(out.resolve()))
    for p in doc["parameters"]:
        if p["no"] == 52:
            p["value"] = "map.csv"
            p["source"] = (f"measured: the part's valve on its active-valve bench, {record} (sha256 {sha[:16]}), "
                           f"by dampertwin fit active-valve on the grid of {d.path or 'the design'}")
    return loads(yaml.safe_dump(doc, sort_keys=False), base_dir=out, where=str(out / "design.yaml")).dump(
        out / "design.yaml")


def fit_active_valve(data, *, design=None, out=None) -> dict:
    """The part's active-valve P/Q map (no. 52) from its active-valve bench record
    (conf/test/activevalve.yaml; :mod:`dampertwin.calibration.active_valve_map`) on the
    design's map grid. With ``out``: map.csv, pq.png, design.yaml (the design with no. 52
    naming map.csv) and fit.json (how far the part lies from the design's map per current)."""
    import matplotlib.pyplot as plt

    from . import report
    from .calibration.active_valve_map import map_change, map_from_record, ordering_flags
    from .design import write_map
    from .io import read_record

    d = _load(design)
    if d.pq_map is None:
        raise FitError(f"{d.path or 'design'}: a {d.architecture} design has no active valve (no P/Q map, no. 52); "
                       f"an active-valve fit needs a design with one")
    path = Path(data)
    meas, meta = read_record(path, "activevalve")
    built, moved = map_from_record(meas, d.pq_map, str(path))
    result = {"submodel": "active-valve", "design": str(d.path) if d.path else None, "design_hash": d.hash(),
              "synthetic": bool(meta.get("synthetic", False)),
              "method": "per current: isotonic least squares of flow on dp (up and down ramps together) read at "
                        "the design's grid; then the map's orderings by alternating least-squares projections",
              "grid": {"currents [A]": [float(c) for c in built.currents], "dp [Pa]": [float(p) for p in built.dps]},
              "outputs": {"map": "map.csv", "design": "design.yaml", "plot": "pq.png"},
              "change_from_design_map": map_change(built, d.pq_map, moved),
              "flags": ordering_flags(built, moved),
              "files": {str(path): {"role": "fitted", "runs": int(meas["run"].nunique()), "samples": len(meas)}}}

    if out is not None:  # a run killed while writing leaves no design.yaml naming another run's map
        for p in check_targets(fit_outputs("active-valve", out, [])):
            p.unlink(missing_ok=True)

    def outputs(o: Path) -> None:
        write_map(o / "map.csv", built)
        _design_with_map(d, o, str(path), _sha(path))
        fig = report.active_valve_map_figure(meas, built, d.pq_map, f"active valve: {path.name} vs the design's map")
        fig.savefig(o / "pq.png", dpi=100)
        plt.close(fig)

    _with_shas(result, out, outputs)
    return result


__all__ = ["read_fit_record", "fit_valve", "fit_compliance", "fit_topmount", "fit_friction", "fit_damper",
           "fit_active_valve"]
