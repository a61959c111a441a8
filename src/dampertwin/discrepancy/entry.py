"""The command-line / stage entry of the discrepancy workflow: the only place
that reads the measured folder and the configuration and writes
``OUT/verdict.json``, ``OUT/design.yaml``, ``OUT/report.md`` and
``OUT/plots/*.png``."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ..design import ConfigTextError, DesignError, load, yaml_load_file
from ..errors import UserError
from ..io import check_out_dir, json_safe, read_record, runs
from ..protocols import flow_bench, load_protocol
from ..variants import load_variant
from . import features as F
from .settings import decision_errors, profile_errors
from .workflow import Problem, record_pool, run, verdict_document

CONFIGURATIONS = {"flowbench": "valve", "compliance": "damper", "curving": "damper", "monosine": "module", "random": "module",
                  "training": None, "verification": None, "thermal": "damper",
                  "friction": "damper", "dyno": "damper"}
PROFILES = ("ci", "full")
VALVE_MAPS = ("record", "design")  # --valve-map: the part's own map from its bench record, or the design's
PART_RECORD = Path("activevalve") / "baseline.parquet"  # the part's active-valve bench record (stage activevalve_map)
PART_MAP = "active_valve_part.csv"  # that map's file beside OUT/design.yaml


class DiscrepancyError(UserError):
    """Unusable input of the discrepancy workflow (the message names the file)."""


def _conf_dir() -> Path:
    from ..config import repo_root

    try:  # relative to the working folder: messages and reports name no machine's folders
        return Path(os.path.relpath(repo_root(Path.cwd()) / "conf"))
    except FileNotFoundError:
        return repo_root(Path(__file__).parent) / "conf"


def load_config(conf: Path) -> dict:
    path = conf / "discrepancy.yaml"
    try:
        doc = yaml_load_file(path)
    except (ConfigTextError, FileNotFoundError) as e:
        raise DiscrepancyError(f"{path}: {e}") from None
    need = ("profiles", "features", "calibration_pool", "decision")
    if not isinstance(doc, dict) or any(k not in doc for k in need):
        raise DiscrepancyError(f"{path}: expected the keys {', '.join(need)}")
    profiles = doc["profiles"]
    bad = decision_errors(doc["decision"])
    if not isinstance(profiles, dict):
        bad.append(f"profiles: {profiles!r}; expected a mapping of {', '.join(PROFILES)}")
    else:
        bad += [e for name, prof in profiles.items() for e in profile_errors(str(name), prof)]
    if bad:
        raise DiscrepancyError([f"{path}: invalid settings"] + bad)
    return doc


def load_design(path: Path, conf: Path):
    """The design under test; unknown keys, bad values or a missing file
    are a DiscrepancyError naming the file."""
    if not path.is_file():
        raise DiscrepancyError(f"{path}: " + ("a folder; expected a design YAML file" if path.is_dir()
                                              else "design file not found"))
    try:
        return load(path, map_dirs=[conf / "design"])
    except DesignError as e:
        raise DiscrepancyError([f"{path}: invalid design"] + list(e.errors)) from None


def check_complete(measured: Path) -> None:
    """The measured folder exists and is not a lab run that stopped (its marker)."""
    if not measured.is_dir():
        raise DiscrepancyError(f"{measured}: measured folder not found (expected DIR/<test>/<case>.parquet)")
    if (measured / ".incomplete").is_file():  # lab.INCOMPLETE: a lab run that did not finish
        raise DiscrepancyError(f"{measured}: written by a lab run that did not finish (its {measured / '.incomplete'} "
                               f"marker); its records may be partial: run the lab again")


def part_valve_map(design, measured: Path, conf: Path, use: str = "record"):
    """The design with its active valve's P/Q map (no. 52) built from the measured folder's
    active-valve bench record (PART_RECORD; calibration.active_valve_map, on the design's grid) when
    ``use`` is 'record', and a note saying what was done; the design unchanged otherwise (note None
    without a record). The map is a measurement of this part, where the design's is usually its
    supplier's datasheet: the workflow's gap is then not the datasheet's error."""
    from ..calibration.active_valve_map import map_change, map_from_record, ordering_flags

    if use not in VALVE_MAPS:
        raise DiscrepancyError(f"--valve-map {use!r}: expected one of {', '.join(VALVE_MAPS)}")
    check_complete(measured)
    rec = measured / PART_RECORD
    others = sorted(str(f) for f in (measured / PART_RECORD.parent).glob("*.parquet") if f != rec)
    other = f" ({', '.join(others)}: not read; the part's map comes from {PART_RECORD})" if others else ""
    if not rec.is_file():
        if design.pq_map is None or use == "design":
            return design, (f"{measured / PART_RECORD.parent}: not read{other}" if others else None)
        return design, (f"{rec}: no active-valve bench record; the design's P/Q map (no. 52, "
                        f"{design.param(52).value}) is used{other}")
    if design.pq_map is None:
        return design, f"{rec}: an active-valve record; the {design.architecture} design has no active valve; ignored"
    if use == "design":
        return design, f"{rec}: the part's active-valve record, not used (--valve-map design keeps the design's map)"
    meas, _ = read_record(rec, "activevalve", conf=conf)
    pq, moved = map_from_record(meas, design.pq_map, str(rec))
    cur, ch = max(map_change(pq, design.pq_map).items(), key=lambda kv: abs(kv[1]["largest_change [m^3/s]"]))
    flags = "".join(f"; WARNING: {f}" for f in ordering_flags(pq, moved))
    note = (f"{rec}: the design's active-valve P/Q map (no. 52) replaced by the part's own from this bench record, on "
            f"the same grid (largest change {ch['largest_change [m^3/s]'] * 6e4:+.4g} l/min at "
            f"{ch['at_dp [Pa]'] / 1e5:.4g} bar, {cur} A){flags}; --valve-map design keeps the design's map{other}")
    source = f"measured: the part's valve on its active-valve bench, {rec} (dampertwin discrepancy)"
    return design.with_pq_map(pq, PART_MAP, source), note


def read_units(measured: Path, design, conf: Path, fcfg: dict, prof: dict, tests: dict | None = None):
    """Units of every usable record of the measured folder the profile selects.
    Returns (units, variants by case, skipped notes)."""
    check_complete(measured)
    present = {p.name: sorted(p.glob("*.parquet")) for p in sorted(measured.iterdir()) if p.is_dir()}
    present = {k: v for k, v in present.items() if v}
    usable = {k: v for k, v in present.items() if k in CONFIGURATIONS}
    notes = [f"{measured / k}: not a test this workflow reads ({', '.join(CONFIGURATIONS)}); ignored"
             for k in present if k not in CONFIGURATIONS and Path(k) != PART_RECORD.parent]  # part_valve_map
    for p in sorted(measured.iterdir()):
        other = sorted(f.name for f in p.iterdir() if f.is_file() and f.suffix != ".parquet") if p.is_dir() else []
        if other:
            notes.append(f"{p}: {', '.join(other)}: not .parquet; ignored")
    if not usable:
        raise DiscrepancyError(f"{measured}: no test records; expected DIR/<test>/<case>.parquet with <test> one of "
                               f"{', '.join(CONFIGURATIONS)} (found: {', '.join(present) or 'nothing'})")
    want = prof["tests"] if tests is None else tests
    maxd = prof.get("max_duration", {}) or {}
    units, variants = [], {}
    # the current range of the active valve's map (a passive design reads no current: not checked)
    current_range = ((float(design.pq_map.currents[0]), float(design.pq_map.currents[-1]))
                     if design.pq_map is not None else None)
    for test, files in usable.items():
        sel = want.get(test, [])
        if sel != "all":
            files = [f for f in files if f.stem in (sel or [])]
        if not files:
            left = tests is not None and prof["tests"].get(test)  # the profile reads it; the caller left it out
            notes.append(f"{test}: present, left out by the caller (the DVC stage reads only the tests it declares; "
                         f"`dampertwin discrepancy` reads them)" if left else f"{test}: present, not used in this profile")
            continue
        proto_path = conf / "test" / f"{test}.yaml"
        proto = load_protocol(proto_path)
        cfg_name = CONFIGURATIONS[test] or proto["configuration"]
        bench = flow_bench(proto) if cfg_name == "valve" else None
        flow_cut = _flow_input_cutoff(conf) if cfg_name == "valve" else None
        for f in files:
            df, meta = read_record(f, test, conf=conf, current_range=current_range)  # the one measurement reader
            case = f.stem
            vpath = conf / "variant" / f"{case}.yaml"
            if test in ("monosine", "random", "training", "verification") and vpath.is_file():
                v = load_variant(vpath)
                try:
                    v.apply(design)
                except (DesignError, UserError) as e:
                    notes.append(f"{f}: variant {case} does not apply to the design ({e}); skipped")
                    continue
                variants[case] = v
            for name, g in _segments(test, df, f, design):
                if cfg_name == "valve" and str(name) not in proto.get("valves", {}):
                    raise DiscrepancyError(f"{f}: " + ("no 'run' column naming the valve" if name is None else
                                                       f"run {name!r} is not a flow-bench valve")
                                           + f" of {proto_path} (expected one of {', '.join(proto.get('valves', {}))})")
                cur = float(g["current [A]"].iloc[0]) if "current [A]" in g else 1.6
                if cfg_name != "valve" and not F.keep_run(test, cur, g["time [s]"].to_numpy(float),
                                                          g["displacement [m]"].to_numpy(float),
                                                          prof.get("run_filter")):
                    continue
                try:
                    u = F.make_unit(test, case, str(name), cfg_name, cur, g, proto.get("sensors", {}), maxd.get(test),
                                    bench=bench, flow_cutoff=flow_cut)
                    F.prepare(u, fcfg)
                except ValueError as e:
                    raise DiscrepancyError(f"{f}: {e}") from None
                units.append(u)
    if not units:
        wanted = "; ".join(f"{k}/{'*' if v == 'all' else '{' + ','.join(v) + '}'}.parquet"
                           for k, v in want.items() if v)
        raise DiscrepancyError(f"{measured}: no record of the tests this profile uses ({wanted}); present: "
                               + ", ".join(f"{k}/{{{','.join(f.stem for f in v)}}}" for k, v in present.items()))
    return units, variants, notes


def _segments(test: str, df, f: Path, design) -> list:
    """The runs of a record; a dyno run cut into its speed steps (features.dyno_segments), with the current
    a semi-active design needs (a dyno export of a passive damper has none: 0 A, not read)."""
    if test != "dyno":
        return runs(df)
    out = []
    for name, g in runs(df):
        if "current [A]" not in g:
            if design.pq_map is not None:
                raise DiscrepancyError(f"{f}: a dyno record of the semi-active design {design.name!r} needs a "
                                       f"'current [A]' column")
            g = g.assign(**{"current [A]": 0.0})
        try:
            out += F.dyno_segments(str(name if name is not None else "dyno"), g)
        except ValueError as e:
            raise DiscrepancyError(f"{f}: {e}") from None
    return out


def _flow_input_cutoff(conf: Path) -> float:
    """[Hz] low-pass of the recorded flow used as the flow-bench input: the valve fits' own value
    (conf/calibration/valves.yaml ``input_cutoff``), so both see the same input."""
    path = conf / "calibration" / "valves.yaml"
    try:
        value = float(yaml_load_file(path)["input_cutoff"])
    except (OSError, KeyError, TypeError, ValueError) as e:
        raise DiscrepancyError(f"{path}: input_cutoff: expected a flow low-pass frequency in Hz ({e})") from None
    if not value > 0:
        raise DiscrepancyError(f"{path}: input_cutoff: expected a positive frequency in Hz, got {value}")
    return value


def main(design: str, measured: str, out: str, profile: str = "ci", seed: int = 0, progress: bool = True,
         tests: dict | None = None, workers: int | None = None, scheduler: str | None = None,
         valve_map: str = "record") -> dict:
    """Run the workflow and write OUT atomically. Returns the verdict document.
    ``workers`` processes simulate the records in parallel (default: the
    machine's cores; 1: in this process, e.g. inside a Dask task); with a
    Dask ``scheduler`` address the records are tasks on that cluster
    instead (``workers`` unused). Same numbers either way. ``valve_map``:
    see :func:`part_valve_map`."""
    if not (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0):
        raise DiscrepancyError(f"--seed {seed!r}: expected a non-negative integer")
    check_out(Path(out), Path(measured), Path(design))
    conf = _conf_dir()
    cfg = load_config(conf)
    if profile not in cfg["profiles"]:
        raise DiscrepancyError(f"{conf / 'discrepancy.yaml'}: no profile {profile!r}; expected one of "
                               f"{', '.join(cfg['profiles'])}")
    d, map_note = part_valve_map(load_design(Path(design), conf), Path(measured), conf, valve_map)
    prof = cfg["profiles"][profile]
    units, variants, notes = read_units(Path(measured), d, conf, cfg["features"], prof, tests)
    notes = [map_note, *notes] if map_note else notes
    problem = Problem(units, cfg["features"], variants, progress=progress)
    if scheduler:
        from ..parallel import DaskMap

        problem.executor = DaskMap(scheduler).executor()
    else:
        problem.executor = record_pool(workers)
    done = False
    try:
        doc = _run_and_write(d, problem, cfg, profile, seed, notes, design, measured, out)
        done = True
        return doc
    finally:
        ex = problem.executor
        if ex is not None:
            if not done:  # interrupted or failed: do not wait for the simulations under way
                for proc in list(getattr(ex, "_processes", {}).values()):  # CPython's pool keeps its workers here
                    proc.terminate()
            ex.shutdown(wait=done, cancel_futures=True)


def check_out(out: Path, measured: Path, design: Path) -> None:
    """OUT is checked before any work, since it will be replaced as a whole:
    it must be a folder (or not exist yet, under a folder), must not hold the
    working directory, the measured folder or the design file, and an
    existing OUT may hold only what the workflow writes
    (:func:`is_earlier_output`): anything else is refused, never deleted."""
    check_out_dir(out, sibling=True)  # a folder or nothing yet, under a writable folder (the temporary sibling)
    o = out.resolve()
    parent = o.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise DiscrepancyError(f"--out {out}: {parent} is a file, not a folder")
    for what, p in (("the working directory", Path.cwd()), ("the measured folder", measured), ("the design file", design)):
        p = p.resolve()
        if p == o or o in p.parents:
            raise DiscrepancyError(f"--out {out}: holds {what} ({p}); OUT is replaced as a whole, choose another folder")
    if o.is_dir() and not is_earlier_output(o):
        raise DiscrepancyError(f"--out {out}: exists and holds files this workflow does not write; refusing to "
                               f"replace it (expected only {', '.join(sorted(OUTPUT_NAMES))} and the P/Q map's .csv)")


OUTPUT_NAMES = {"verdict.json", "design.yaml", "report.md", "plots", "resolvability.json", ".gitignore"}


def is_earlier_output(folder: Path) -> bool:
    """Empty, or only what this workflow writes (a DVC stage's .gitignore included; the
    P/Q map's .csv beside a design.yaml or verdict.json)."""
    names = {p.name for p in folder.iterdir()}
    ours = names <= OUTPUT_NAMES | {n for n in names if n.endswith(".csv")}
    csv_ok = not any(n.endswith(".csv") for n in names) or bool(names & {"design.yaml", "verdict.json"})
    return ours and csv_ok


def _run_and_write(d, problem, cfg, profile, seed, notes, design, measured, out) -> dict:
    from .report import write_report

    res = run(d, problem, cfg, profile, int(seed))
    res["notes"] = notes
    doc = verdict_document(res)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp", dir=out.parent))
    old = None
    try:
        _dump_design(res["design"], tmp)
        (tmp / "verdict.json").write_text(json.dumps(json_safe(doc), indent=2, allow_nan=False) + "\n")
        # `none` / `unexplained`: what these records could have seen ([] when the check did not run)
        (tmp / "resolvability.json").write_text(json.dumps(json_safe(res.get("resolvability") or []), indent=2,
                                                           allow_nan=False) + "\n")
        write_report(tmp, d, problem, res, doc, {"design": design, "measured": measured, "profile": profile,
                                                 "seed": int(seed)})
        old = None
        if out.exists():  # an earlier output (check_out): moved aside, then the new one moved in
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old", dir=out.parent))
            os.replace(out, old / out.name)
        try:
            os.replace(tmp, out)
        except OSError:
            if old is not None:  # the earlier output goes back where it was
                os.replace(old / out.name, out)
            raise
        if old is not None and (old / out.name / ".gitignore").is_file():  # a DVC stage's: kept
            os.replace(old / out.name / ".gitignore", out / ".gitignore")
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
        if old is not None and old.exists():  # never an (empty) .NAME.old* left behind
            shutil.rmtree(old, ignore_errors=True)
    # the augmented design must load from its new place, on its own
    load(out / "design.yaml")
    return doc


def _dump_design(design, folder: Path) -> None:
    """OUT/design.yaml with its P/Q map beside it (a design that loads on its own)."""
    from ..design import write_map

    if design.pq_map is None:  # a passive architecture: no map beside it
        (folder / "design.yaml").write_text(design.dumps(folder.resolve()))
        return
    rel = str(design.param(52).value)
    name = Path(rel).name
    write_map(folder / name, design.pq_map)
    text = design.dumps(folder.resolve())
    lines = text.splitlines(keepends=True)
    out, in52 = [], False
    for line in lines:
        if line.startswith(("- no: ", "- 'no': ")):
            in52 = line.split(":", 1)[1].strip() == "52"
        if in52 and line.lstrip().startswith("value: "):
            line = line[: line.index("value: ")] + f"value: {name}\n"
        out.append(line)
    (folder / "design.yaml").write_text("".join(out))
