"""Hidden-effect matrix of the discrepancy workflow (issue 11, acceptance 1).

Generates SYNTHETIC lab data with `dampertwin lab` (dampertwin.lab.run_lab)
for cases drawn from the arguments (seeds and magnitudes come from the
command line; nothing is stored as an expected answer), runs the workflow
from the nominal design (ci profile) on each, and prints ONE JSON line:
counts per cell and the rates of the issue.

Two labs (--lab):

truth (default; issue 34): the reference damper dampertwin.truth, written
from other physics than the model, on the shipped sample's benches
(conf/lab/sample.yaml). The hidden effects are the truth's own physics
(truth.params.OFF_BY_DEFAULT), never a candidate's equation; the expected
answer of each is the library table's ``truth_effects`` column
(model.params.EFFECTS_LIBRARY): the families that approximate it.
  control   the sample's part deviations from the truth's nominal scaled by
            u ~ U(0, --dev-scale) in log space (up to 1.5x today's), no
            hidden effect: a deviation that IS a hidden effect's magnitude
            (the shipped sample's worn band, chambers.BAND_H 30 um) stays at
            the new part's value (HIDDEN_VALUE_KEYS)
  single    one hidden truth effect at --magnitudes x its typical magnitude
            (TRUTH_MAGNITUDE below: a worn band, air drawn in from a low oil
            level, a two-node thermal network, top-mount free play), nominal part
  pair      two hidden truth effects, each at --pair-magnitude x its typical
            magnitude (default 1); pairs with a member covered by --start-set
            (its every family on at the start) only when no other pair is left
  artefact  out of library: accelerometer mount resonance or load-cell
            crosstalk added to the measured records

    python bench/discrepancy.py --controls 12 --per-effect 3 --pairs 12 --artefacts 12 --seed 11

(60 cases; run it with two fresh seeds).

library (issue 11, the earlier matrix): lab 2, whose hidden effects are the
library candidates' own equations (conf/lab/lab2/sample.yaml).
  control   nominal part with parameter deviations within bounds (random
            factors, --dev spread), no effect
  single    one library effect (effect_parameters typical magnitude x --scale)
  pair      two library effects together
  artefact  as above

    python bench/discrepancy.py --lab library --controls 10 --per-effect 3 --pairs 5 --artefacts 5
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

from dampertwin.design import DesignError, load  # noqa: E402
from dampertwin.discrepancy import catalogue, entry  # noqa: E402
from dampertwin.discrepancy.hidden import accelerometer_resonance, hidden_sample, loadcell_crosstalk  # noqa: E402
from dampertwin.io import read_meta, write_frame  # noqa: E402
from dampertwin.lab import LAB_VERSION, TRUTH_ATOL, TRUTH_RTOL, load_sample, run_lab  # noqa: E402
from discrepancy_score import (always_on_families, families, foreign, lead_figures, named_beside, score,  # noqa: E402,F401
                               start_on)
from model_error import overrides  # noqa: E402

# A hidden truth effect's magnitude: the parameter (truth.params.EFFECT_PARAMETERS; a key with a dot is a
# truth value) and how a magnitude factor m acts on its typical value ("mul": x m; "div": / m, for a
# conductance whose smallness IS the effect), and the case's other settings (effect parameters or truth
# values). A band is hidden as a WORN band: 30 um radial clearance at m = 1 (the model's piston_leakage
# source: 30-60 um worn; the new part's 8 um leaks ~1e-8 m^3/s at 20 bar, below every record's noise,
# docs/validation/discrepancy-matrix.md), off-axis by half of it. Air is entrained from a LOW OIL LEVEL: the
# onset 6 bar abs lies above the 4 bar precharge, so every intake stroke draws gas (at the truth's 2.5 bar
# onset the reserve never falls low enough in these tests and the records do not change).
TRUTH_MAGNITUDE = {"band_eccentricity": ("chambers.BAND_H", "mul", 3e-5, {"eccentricity": 0.5}),
                   "two_node_thermal": ("oil_to_steel", "div", None, {}),
                   "top_mount_free_play": ("clearance", "mul", None, {}),
                   "air_entrainment": ("fraction", "mul", None, {"onset_pressure": 6e5})}

# Truth values that are a hidden effect's magnitude (a worn band's clearance): a control keeps the new part's
# value. The shipped sample's part carries a worn band (30 um); scaled with the other deviations it gave the
# controls bands of 8-58 um, the band cell's own range, so a control hid the worn band it was to be told from
# (seed 31's control 0: 48 um, 0.45 l/min past the band at 0.1 m/s; docs/validation/discrepancy-matrix.md).
HIDDEN_VALUE_KEYS = frozenset(q for q, *_ in TRUTH_MAGNITUDE.values() if "." in q)

DEV_KEYS = ["piston_rebound.a", "piston_rebound.F_preload", "piston_intake.a", "base_compression.a",
            "base_compression.F_preload", "base_intake.a", "top_mount.k0", "top_mount.c0", "rod_friction.F_c"]


def truth_cases(args, base: dict, rng) -> tuple[list, list]:
    """The truth lab's cells (module docstring): hidden truth effects by their own physics."""
    from dampertwin.truth.params import EFFECT_PARAMETERS, OFF_BY_DEFAULT, TRUTH_NOMINAL, nominal

    nom = {**TRUTH_NOMINAL, **nominal(load(ROOT / "conf" / "lab" / "nominal.yaml"))}
    dev = base["truth"].get("values", {})
    hidden = [h for h in OFF_BY_DEFAULT if not args.effects or h in args.effects.split(",")]

    def at(h, m):
        """(the effect's parameters, truth values) of hidden effect h at magnitude m."""
        q, how, typical, other = TRUTH_MAGNITUDE[h]
        key, lo, hi = EFFECT_PARAMETERS[h][q] if "." not in q else (q, 0.0, math.inf)
        x = (TRUTH_NOMINAL[key] if typical is None else typical) * (m if how == "mul" else 1.0 / m)
        x = float(min(max(x, lo), hi))
        return ({**other, q: x}, {}) if "." not in q else (dict(other), {q: x})

    def hide(*hm):
        """The case's spec hiding effects h at magnitudes m."""
        done = [(h, at(h, m)) for h, m in hm]
        return {"effects": {h: e for h, (e, _) in done}, "values": {k: x for _, (_, v) in done for k, x in v.items()}}

    out = []
    for i in range(args.controls):
        u = float(rng.uniform(0.0, args.dev_scale))
        # log-space scaling of each deviation from the truth's nominal; a key without a nominal
        # (a shim-stack drawing) keeps its deviation
        vals = {k: (nom[k] * (v / nom[k]) ** u if nom.get(k, 0) > 0 and v > 0 else v) for k, v in dev.items()
                if k not in HIDDEN_VALUE_KEYS}
        out.append(("control", [], {"values": vals}, None))
    for h in hidden:
        for m in args.magnitudes:
            for i in range(args.per_effect):
                mm = float(m * np.exp(rng.normal(0, 0.1)))
                out.append(("single", [h], hide((h, mm)), None))
    # a pair whose member is covered at the start (--start-set: every family of it on and calibrated) is
    # a single case in disguise, since that member cannot be named: such pairs come only when no other is left
    on = start_on(getattr(args, "start_set", {}))
    pairs = [(a, b) for i, a in enumerate(hidden) for b in hidden[i + 1:]]
    pairs = [p for p in pairs if all(families([h], "truth", on) for h in p)] or pairs
    m = getattr(args, "pair_magnitude", 1.0)
    for i in range(args.pairs if pairs else 0):
        a, b = pairs[i % len(pairs)]
        out.append(("pair", [a, b], hide((a, m), (b, m)), None))
    out += _artefacts(args, rng)
    return out, hidden


def _artefacts(args, rng) -> list:
    out = []
    for i in range(args.artefacts):
        if i % 2 == 0:
            art = ("accel", float(rng.uniform(150, 400)), float(rng.uniform(0.05, 0.12)))
        else:
            art = ("xtalk", float(rng.uniform(0.02, 0.05)), 0.0)
        out.append(("artefact", [], {}, art))
    return out


def cases(args, design, cfg, rng):
    cands = catalogue(design, cfg)
    if args.effects:  # a targeted check: single and pair cases of these effects only
        want = args.effects.split(",")
        unknown = sorted(set(want) - {c.name for c in cands})
        if unknown:
            raise SystemExit(f"--effects: unknown {', '.join(unknown)}; expected some of {', '.join(c.name for c in cands)}")
        cands = [c for c in cands if c.name in want]
    out = []
    keys = DEV_KEYS
    if args.dev_keys == "pool":  # every calibration parameter (the oil temperature is the lab's bench condition)
        keys = [k for k in cfg["calibration_pool"] if k != "oil.T"]
    for i in range(args.controls):
        f = {k: float(np.exp(rng.normal(0, args.dev))) for k in keys}
        if "rod_friction.F_c" in f and "rod_friction.F_s" in f:  # a real seal keeps F_c <= F_s (eq. 4.41)
            fs = f["rod_friction.F_s"] * design["rod_friction.F_s"]
            f["rod_friction.F_c"] = min(f["rod_friction.F_c"], fs / design["rod_friction.F_c"])
        out.append(("control", [], {"factors": f}, None))
    for c in cands:
        for i in range(args.per_effect):
            s = float(args.scale * np.exp(rng.normal(0, 0.2)))
            vals = {k: v * s if k in {p.key for p in c.params} else v for k, v in c.typical.items()}
            for p in c.params:  # keep inside the bounds
                vals[p.key] = float(min(max(vals[p.key], p.lo), p.hi))
            out.append(("single", [c.name], {"effects": {c.name: True}, "values": vals}, None))
    names = [c.name for c in cands]
    for i in range(args.pairs if len(cands) >= 2 else 0):
        a, b = rng.choice(len(cands), 2, replace=False)
        ca, cb = cands[a], cands[b]
        out.append(("pair", [ca.name, cb.name], {"effects": {ca.name: True, cb.name: True},
                                                 "values": {**ca.typical, **cb.typical}}, None))
    out += _artefacts(args, rng)
    return out, names


VALVES = ("piston_rebound", "piston_intake", "base_compression", "base_intake")


MEASURED_MAP = "active_valve_measured.csv"  # the part's P/Q map beside the approach-1 start design


def approach1_design(conf: Path, data: Path, seed: int, out: Path) -> Path:
    """The study's starting point for the workflow (stages flowbench_fit, compliance_fit,
    topmount_fit, assemble for baseline_1.6): the baseline design with its four valves fitted on
    the case's flow-bench records, then the compliance and the top mount, ci-profile GA and polish
    budgets, the stages' order; with an active-valve bench record (activevalve/baseline), the
    active valve's own P/Q map built from it in place of the datasheet's (stage activevalve_map).
    Returns the calibrated design's path."""
    from omegaconf import OmegaConf

    from dampertwin.calibration.approach1 import fit_compliance, fit_top_mount, fit_valve
    from dampertwin.calibration.ga import GASettings
    from dampertwin.calibration.polish import PolishSettings
    from dampertwin.design import yaml_load_file
    from dampertwin.io import read_record
    from dampertwin.protocols import load_protocol

    prof = OmegaConf.load(conf / "profile" / "ci.yaml")
    pol = PolishSettings.from_config(prof.polish)
    d = base = load(conf / "design" / "baseline.yaml")
    cal = yaml_load_file(conf / "calibration" / "valves.yaml")
    fb = load_protocol(conf / "test" / "flowbench.yaml")
    bench = {"bench_volume": fb["volume"], "bench_back_pressure": fb["back_pressure"]}
    for k, v in enumerate(VALVES):
        meas, _ = read_record(data / "flowbench" / f"{v}.parquet", "flowbench", conf=conf, valve=v)
        res = fit_valve(base, v, meas, cal, GASettings.from_config(prof.ga.valves), seed + k, bench=bench,
                        progress=False, polish_settings=PolishSettings.from_config(prof.polish, "valves"))
        d = d.with_overrides(res.best)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "start_design.yaml"
    rec = data / "activevalve" / "baseline.parquet"
    if rec.is_file():  # before the compliance fit: its test runs through the active valve
        from dampertwin.calibration.active_valve_map import map_from_record
        from dampertwin.design import write_map

        meas, _ = read_record(rec, "activevalve", conf=conf)
        write_map(out / MEASURED_MAP, map_from_record(meas, d.pq_map, str(rec))[0])
        d.dump(path)
        d = load(path, map_dirs=[conf / "design"]).with_overrides({"active_valve.pq_map": MEASURED_MAP})
    keep = lambda b: {k: x for k, x in b.items() if not k.startswith("sensor.")}  # noqa: E731 (nuisance keys)
    bw = load_protocol(conf / "test" / "compliance.yaml").get("sensors", {}).get("force")
    meas, _ = read_record(data / "compliance" / "baseline.parquet", "compliance", conf=conf)
    res = fit_compliance(d, meas, yaml_load_file(conf / "calibration" / "compliance.yaml"),
                         GASettings.from_config(prof.ga.compliance), seed + 4, progress=False,
                         polish_settings=pol, force_bandwidth=bw)
    d = d.with_overrides(keep(res.best))
    bw = load_protocol(conf / "test" / "topmount.yaml").get("sensors", {}).get("force")
    meas, _ = read_record(data / "topmount" / "baseline.parquet", "topmount", conf=conf)
    res, coef, _ = fit_top_mount(base, meas, yaml_load_file(conf / "calibration" / "topmount.yaml"),
                                 GASettings.from_config(prof.ga.topmount), seed + 5, progress=False,
                                 polish_settings=pol, force_bandwidth=bw)
    d = d.with_overrides({**keep(res.best), "top_mount.F_LD": coef})
    d.dump(path)
    return path


def _generate(it: dict, spec: dict, name: str) -> bool:
    """Lab records of ``spec`` into WORK/name (SYNTHETIC), the case's seed, tests and artefact; True when
    the records of an earlier run were reused. A rerun in the same --work folder reuses them when
    everything that made them is the same (sample, seed, tests, artefact, LAB_VERSION, truth tolerances:
    a lab code change without a version bump is not seen, use a new --work then); the stamp is written
    last, so a killed generation is redone."""
    conf, work = Path(it["conf"]), Path(it["work"])
    s = hidden_sample(it["base"], **spec)
    if "truth" not in s:  # lab 2: the part is the nominal design's (lab 3 names its drawings itself)
        s["nominal"] = str(conf / "lab" / "nominal.yaml")
    sp = work / f"{name}.yaml"
    sp.write_text(yaml.safe_dump(s))
    data, art = work / name, it["art"]
    stamp = data / ".case.json"
    made = json.dumps({"sample": sp.read_text(), "seed": it["seed"], "only": [list(x) for x in it["only"]],
                       "art": art, "lab": LAB_VERSION, "truth": [TRUTH_RTOL, TRUTH_ATOL]},
                      sort_keys=True)
    if stamp.is_file() and stamp.read_text() == made:
        return True
    shutil.rmtree(data, ignore_errors=True)
    run_lab(sp, data, seed=it["seed"], only=it["only"], progress=False, workers=it["lab_workers"], conf=conf)
    if art is not None:
        for f in data.glob("*/*.parquet"):
            df = pq.read_table(f).to_pandas()
            df = accelerometer_resonance(df, art[1], art[2]) if art[0] == "accel" else loadcell_crosstalk(df, art[1])
            write_frame(f, df, {**read_meta(f), "artefact": list(art)})
    stamp.write_text(made)
    return False


def visibility(conf: Path, data: Path, data_off: Path, tests: dict) -> dict:
    """How far the hidden effects move the records, in the workflow's own noise units: the records of
    the case (``data``) against the same part, seed and lab noise without the hidden effects
    (``data_off``), whitened by the workflow's noise model (features.noise on the measured scatter,
    the bench allowances; Problem.set_noise). ``ratio`` is the workflow's record gate on that
    difference (decision.worst_record: chi^2 / its Bonferroni quantile): above 1, a model without
    any model error would see the effect in ``record``; ``rms_z`` over every feature."""
    from dampertwin.discrepancy.decision import worst_record
    from dampertwin.discrepancy.problem import Problem, Row

    cfg = entry.load_config(conf)
    prof = cfg["profiles"]["ci"]
    d = entry.load_design(conf / "design" / "baseline.yaml", conf)
    on, variants, _ = entry.read_units(data, d, conf, cfg["features"], prof, tests)
    off, _, _ = entry.read_units(data_off, d, conf, cfg["features"], prof, tests)
    if [u.key for u in on] != [u.key for u in off]:
        raise SystemExit(f"{data} and {data_off}: different records")
    problem = Problem(on, cfg["features"], variants, progress=False)
    problem.set_noise(Row([np.full_like(u.per_cycle, np.nan) for u in off]))  # the measured scatter alone
    z = problem.z(Row([u.per_cycle for u in off]))
    ratio, record = worst_record(problem, z, np.ones(len(z), bool), float(cfg["decision"]["record_alpha"]))
    return {"ratio": round(ratio, 4), "record": record, "rms_z": round(float(np.sqrt(np.mean(z * z))), 4)}


def one_case(it: dict) -> dict:
    """Lab records of one hidden-effect case (SYNTHETIC), then the workflow from its starting design."""
    conf, work, k = Path(it["conf"]), Path(it["work"]), it["k"]
    data = work / f"case{k}"
    t1 = time.time()
    reused = _generate(it, it["spec"], f"case{k}")
    seen = None
    if it.get("visibility") and it["truth"]:  # the same case without its hidden effects
        # without the hidden effects and their settings (a worn band's clearance): the nominal part
        _generate(it, {q: v for q, v in it["spec"].items() if q not in ("effects", "values")}, f"case{k}_off")
        seen = visibility(conf, data, work / f"case{k}_off", it["tests"])
    t_lab = time.time() - t1
    start = conf / "design" / "baseline.yaml"
    if it["start"] == "approach1":  # as the study: the workflow starts from the approach-1 calibrated design
        start = approach1_design(conf, data, it["seed"], work / f"start{k}")
    if it.get("start_set"):  # an iterated workflow's later round: effects added before, on with their values
        (work / f"start{k}").mkdir(parents=True, exist_ok=True)
        d = entry.load_design(start, conf).with_overrides(it["start_set"])
        start = work / f"start{k}" / "start_design_set.yaml"
        d.dump(start)
    t_start = time.time() - t1 - t_lab
    shutil.rmtree(work / f"out{k}", ignore_errors=True)  # the bench's own folder: a rerun replaces it
    doc = entry.main(str(start), str(data), str(work / f"out{k}"), profile="ci",
                     seed=it["seed"], progress=False, tests=it["tests"], workers=it["lab_workers"])
    rfile = work / f"out{k}" / "resolvability.json"   # `none`: against noise; `unexplained`: the misfit too
    rs = {r["effect"]: r for r in json.loads(rfile.read_text())} if rfile.is_file() else {}
    lead = next((c for c in doc["candidates"] if "+" not in c["effect"]), None)  # the first-round ranking's top
    return {"cell": it["cell"], "truth": it["truth"], "verdict": doc["verdict"], "effects": doc["effects"],
            "lead": lead and lead["effect"], "lead_gap_after": lead and lead["heldout_gap_after"],
            "group": doc["group"], "closed": doc["gap"]["closed_fraction"], "gap_before": doc["gap"]["before"],
            "gap_after": doc["gap"]["after"],
            # where the start design and the records disagree most (the model error a control leaves)
            "where": [f"{w['test']}/{w['case']} {w['phase_or_band']}: {w['excess']:g}" for w in doc["where"][:3]],
            "visibility": seen, "lab_s": round(t_lab, 1), "lab_reused": reused,
            "start": it["start"], "start_s": round(t_start, 1), "start_on": start_on(it.get("start_set") or {}),
            "case_s": round(time.time() - t1, 1),
            # the workflow's own statement that the records could not show the hidden effect
            # (truth lab: every family that approximates the effect judged unresolvable)
            "truth_unresolvable": [n for n in it["truth"]
                                   if (fam := families([n], it["lab"], start_on(it.get("start_set") or {})))
                                   and all(rs.get(c, {}).get("resolvable") is False
                                                                                 for c in fam)],
            # the same against the noise alone (an `unexplained`'s check also holds the model error)
            "truth_unresolvable_noise": [n for n in it["truth"]
                                         if (fam := families([n], it["lab"], start_on(it.get("start_set") or {})))
                                         and all(_noise_ratio(rs.get(c, {})) is not None
                                                 and _noise_ratio(rs.get(c, {})) < 1.0 for c in fam)]}


def _noise_ratio(r: dict):
    """A resolvability row's ratio against the noise alone (``ratio_noise`` after an `unexplained`)."""
    return r.get("ratio_noise", r.get("ratio"))


def _one_thread() -> None:
    """Case processes of --jobs: one numba thread each (the cases are the parallelism)."""
    import numba

    numba.set_num_threads(1)


def _magnitude(text: str) -> float:
    """A magnitude factor of the command line: finite and > 0."""
    try:
        x = float(text)
    except ValueError:
        x = math.nan
    if not (math.isfinite(x) and x > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: expected a finite factor > 0 (1 = typical magnitude)")
    return x


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lab", choices=["truth", "library"], default="truth",
                    help="truth: hidden effects in the reference damper's own physics (default); library: lab 2, "
                         "the candidates' own equations")
    ap.add_argument("--pair-magnitude", type=_magnitude, default=1.0,
                    help="truth lab: hidden magnitude / typical magnitude of each effect of a pair case")
    ap.add_argument("--magnitudes", type=lambda t: [_magnitude(x) for x in t.split(",")], default=[0.6, 1.5],
                    help="truth lab: hidden magnitudes / typical magnitude of the single cases")
    ap.add_argument("--dev-scale", type=float, default=1.5,
                    help="truth lab: controls scale the sample's part deviations by U(0, this)")
    ap.add_argument("--start", choices=["approach1", "nominal"], default="approach1",
                    help="the workflow's starting design: approach1 = the case's approach-1 fits (valves, compliance, "
                         "top mount; ci budgets), as the study's discrepancy stage; nominal = conf/design/baseline.yaml")
    ap.add_argument("--start-set", type=overrides, default={}, metavar="KEY=VALUE[,...]",
                    help="overrides of the starting design: an iterated workflow's later round, with the effects "
                         "an earlier round added switched on at its values (the workflow does not offer them; a "
                         "hidden effect whose families are all on is expected as none)")
    ap.add_argument("--controls", type=int, default=10)
    ap.add_argument("--per-effect", type=int, default=3)
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--artefacts", type=int, default=5)
    ap.add_argument("--effects", default=None,
                    help="comma-separated library effects the single / pair cases draw from (default all; a "
                         "targeted check, not the acceptance matrix)")
    ap.add_argument("--seed", type=int, default=0, help="seeds every draw (magnitudes, deviations, lab noise)")
    ap.add_argument("--scale", type=float, default=1.0, help="hidden magnitude / typical magnitude")
    ap.add_argument("--dev", type=float, default=0.05, help="one-sigma log deviation of control parameters")
    ap.add_argument("--dev-keys", choices=["valves", "pool"], default="valves",
                    help="control deviations: valves = DEV_KEYS (valves, top mount k0 / c0, rod friction F_c); "
                         "pool = every calibration_pool parameter but the oil temperature")
    ap.add_argument("--tests", default="flowbench:piston_rebound,flowbench:piston_intake,flowbench:base_compression,"
                                        "flowbench:base_intake,compliance:baseline,monosine:baseline_1.6,"
                                        "monosine:baseline_0.32,random:baseline_1.6,curving:baseline,thermal:baseline,"
                                        "friction:baseline,topmount:baseline,activevalve:baseline",
                    help="lab records generated per case (the ci profile's tests; topmount and activevalve for the "
                         "approach-1 start)")
    ap.add_argument("--visibility", action="store_true",
                    help="also generate each single / pair case without its hidden effects (same part, seed and "
                         "noise) and report how far the effects move the records in the workflow's noise units "
                         "(row `visibility`; the rates among the cases a model without model error would see)")
    ap.add_argument("--lab-workers", type=int, default=None,
                    help="processes generating one case's lab records and simulating its records in the workflow "
                         "(default: all cores locally, 1 per case on a cluster)")
    ap.add_argument("--work", default=None, help="work folder (default: a temporary one, removed)")
    ap.add_argument("--jobs", type=int, default=1,
                    help="cases run at once on this machine, one process each (then 1 lab / record worker per case)")
    ap.add_argument("--scheduler", default=None,
                    help="Dask scheduler address: cases run as tasks on the cluster (work folder shared)")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    conf = ROOT / "conf"
    cfg = entry.load_config(conf)
    design = load(conf / "design" / "baseline.yaml")
    try:  # before any lab run: an unknown key or a bad value of --start-set
        design.with_overrides(args.start_set)
    except DesignError as e:
        raise SystemExit(f"--start-set: {e}") from None
    sample = conf / "lab" / ("sample.yaml" if args.lab == "truth" else "lab2/sample.yaml")
    base = {k: v for k, v in load_sample(sample).items() if not k.startswith("_")}
    only = [tuple(x.split(":")) for x in args.tests.split(",")]
    if args.lab != "truth":  # a lab-2 part has no solenoid valve of its own: the datasheet map stays
        only = [x for x in only if x[0] != "activevalve"]
    tests = {}
    for t, c in only:
        tests.setdefault(t, []).append(c)
    work = Path(args.work or tempfile.mkdtemp(prefix="dt_bench_"))
    work.mkdir(parents=True, exist_ok=True)
    plan, names = truth_cases(args, base, rng) if args.lab == "truth" else cases(args, design, cfg, rng)
    if args.start == "approach1" and not {"flowbench", "compliance", "topmount"} <= set(tests):
        raise SystemExit("--start approach1 needs flowbench, compliance and topmount records in --tests")
    items = [{"k": k, "lab": args.lab, "start": args.start, "start_set": args.start_set, "visibility": args.visibility, "cell": cell, "truth": truth, "spec": spec, "art": art, "seed": int(rng.integers(0, 2**31)),
              "base": base, "conf": str(conf), "work": str(work), "only": only, "tests": tests,
              "lab_workers": args.lab_workers or (1 if args.scheduler or args.jobs > 1 else os.cpu_count() or 1)}
             for k, (cell, truth, spec, art) in enumerate(plan)]
    t0 = time.time()
    if args.scheduler:  # one case per task on the Dask cluster (same function as locally)
        from dampertwin.parallel import DaskMap

        rows = [r for r, _ in DaskMap(args.scheduler)(one_case, items)]
        for r in rows:
            print(json.dumps(r), file=sys.stderr)
    elif args.jobs > 1:  # cases side by side on this machine, one single-threaded process each
        from concurrent.futures import ProcessPoolExecutor
        from multiprocessing import get_context

        from tqdm import tqdm

        with ProcessPoolExecutor(args.jobs, mp_context=get_context("spawn"), initializer=_one_thread) as ex:
            rows = []
            for r in tqdm(ex.map(one_case, items), total=len(items), desc="hidden-effect matrix (cases)",
                          file=sys.stderr):
                rows.append(r)
                tqdm.write(json.dumps(r), file=sys.stderr)
    else:
        from tqdm import tqdm

        rows = []
        for it in tqdm(items, desc="hidden-effect matrix (cases)", file=sys.stderr):
            rows.append(one_case(it))
            tqdm.write(json.dumps(rows[-1]), file=sys.stderr)
    if args.work is None:
        shutil.rmtree(work, ignore_errors=True)

    out = {
        **score(rows, args, names),
        "wall_s_per_case": round((time.time() - t0) / max(len(rows), 1), 1),
    }
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
