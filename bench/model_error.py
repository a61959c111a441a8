"""Where a design and a case's lab records disagree, test by test, in the discrepancy workflow's own
noise units (SYNTHETIC lab data; the measurement log of docs/validation/discrepancy-matrix.md).

For a finished ``bench/discrepancy.py --work`` folder: the case's starting design (``startK/``, the
approach-1 fits; else conf/design/baseline.yaml) against its records (``caseK/``), simulated as the
workflow simulates them (``Problem.simulate``), whitened by the workflow's noise model on that
residual (``Problem.set_noise``). Prints ONE JSON line per design: the mean z^2 per feature of each
test / case (1 = noise) and the gap over every record (sqrt of the mean z^2). ``--set`` adds designs
with overrides (a diagnostic: an effect switched on, a parameter moved); the noise model stays the
start design's, so the rows compare.

    python bench/model_error.py --work /tmp/m31/work --case 0 \\
        --set effects.active_valve_lag=true,active_valve_lag.tau=0.002

``--truth-off`` attributes the model error to the truth's physics: the case's records are made again
(same sample, part, hidden effects, seed, lab noise and artefact; WORK/truth_offK/NAME/, reused when
unchanged) with one or more of the truth's always-on effects switched off (truth.params.EFFECTS, e.g.
``gas_dissolution``, ``shim_friction``, ``current_driver``; ``a+b`` switches off both), and the start
design is compared with them, each set whitened by its own noise model (as the workflow would). A
test whose mean z^2 falls when an effect is off carries that effect's share of the model error.

    python bench/model_error.py --work /tmp/m31/work --case 0 --truth-off gas_dissolution \\
        --truth-off current_driver --tests thermal,curving

A start design written by another checkout names its P/Q map relative to that checkout's
conf/design: give that folder in DAMPERTWIN_MAP_DIRS.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from dampertwin.discrepancy import entry  # noqa: E402
from dampertwin.discrepancy.problem import Problem  # noqa: E402


def overrides(text: str) -> dict:
    """``key=value,key=value`` -> {key: value} (values parsed as YAML scalars)."""
    out = {}
    for item in filter(None, text.split(",")):
        key, sep, val = item.partition("=")
        if not sep or not key.strip():
            raise argparse.ArgumentTypeError(f"{item!r}; expected key=value[,key=value...]")
        out[key.strip()] = yaml.safe_load(val)
    return out


def by_test(problem: Problem, z: np.ndarray) -> dict:
    """Mean z^2 per feature of each test / case."""
    rec = np.array(["/".join(lab[:2]) for lab in problem.labels])
    return {r: round(float(np.mean(z[rec == r] ** 2)), 2) for r in sorted(set(rec))}


def truth_off_records(work: Path, case: int, names: str, stamp: dict, tests: dict) -> Path:
    """The case's records again with the truth's always-on effects ``names`` (``a+b``) switched off,
    into WORK/truth_offK/NAMES (bench/discrepancy.py's generator and stamp: reused when unchanged)."""
    import importlib.util

    from dampertwin.truth.params import EFFECTS, OFF_BY_DEFAULT

    off = [n for n in names.split("+") if n]
    bad = [n for n in off if n not in EFFECTS or n in OFF_BY_DEFAULT]
    if not off or bad:
        known = ", ".join(sorted(set(EFFECTS) - set(OFF_BY_DEFAULT)))
        raise SystemExit(f"--truth-off {names!r}: {', '.join(bad) or 'empty'}; expected the truth's always-on "
                         f"effects joined by '+': {known}")
    base = yaml.safe_load((work / f"case{case}.yaml").read_text())
    if "truth" not in base:
        raise SystemExit(f"--truth-off: {work / f'case{case}.yaml'} is a lab-2 case (no truth: section)")
    spec = importlib.util.spec_from_file_location("bench_discrepancy", ROOT / "bench" / "discrepancy.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)  # its case generator and stamp
    out = work / f"truth_off{case}"
    out.mkdir(exist_ok=True)
    only = [(t, c) for t, cs in tests.items() for c in cs]
    it = {"conf": str(ROOT / "conf"), "work": str(out), "base": base, "seed": stamp["seed"], "only": only,
          "art": stamp.get("art"), "lab_workers": os.cpu_count() or 1}
    gen._generate(it, {"effects": {n: False for n in off}, "keep_deviations": True}, names)
    return out / names


def compare(data: Path, design, conf: Path, cfg: dict, tests: dict, designs: list) -> list[dict]:
    """One row per design (name, design): the gap and the mean z^2 per test of ``data``, whitened by the
    noise model on the first design's residual."""
    units, variants, _ = entry.read_units(data, design, conf, cfg["features"], cfg["profiles"]["ci"], tests)
    problem = Problem(units, cfg["features"], variants, progress=False)
    rows = [problem.simulate([d])[0] for _, d in designs]  # one at a time: a batch shares one P/Q map
    problem.set_noise(rows[0])
    out = []
    for (name, _), row in zip(designs, rows):
        z = problem.z(row)
        if not np.all(np.isfinite(z)):
            raise SystemExit(f"{name}: a record failed to simulate: {problem.failures[-1:]}")
        out.append({"design": name, "gap": round(float(np.sqrt(np.mean(z * z))), 3),
                    "mean_z2_by_test": by_test(problem, z)})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", required=True, help="a bench/discrepancy.py --work folder")
    ap.add_argument("--case", type=int, required=True, help="the case number K (caseK/, startK/)")
    ap.add_argument("--set", action="append", default=[], type=lambda t: (t, overrides(t)),
                    help="a further design: key=value[,key=value...]")
    ap.add_argument("--truth-off", action="append", default=[],
                    help="the records again with the truth's always-on effects off: NAME[+NAME...]")
    ap.add_argument("--tests", default="", help="only these tests (comma-separated, e.g. thermal,curving)")
    ap.add_argument("--start", default=None,
                    help="the starting design (default WORK/startK/start_design.yaml, else conf/design/baseline.yaml)")
    args = ap.parse_args(argv)
    work, conf = Path(args.work), ROOT / "conf"
    data = work / f"case{args.case}"
    stamp = data / ".case.json"
    if not stamp.is_file():
        raise SystemExit(f"{data}: no finished case (its .case.json stamp is missing)")
    start = Path(args.start) if args.start else work / f"start{args.case}" / "start_design.yaml"
    if args.start and not start.is_file():
        raise SystemExit(f"--start {start}: no such design file")
    start = start if start.is_file() else conf / "design" / "baseline.yaml"
    stamp_doc = json.loads(stamp.read_text())
    want = set(filter(None, args.tests.split(",")))
    tests: dict = {}
    for t, c in stamp_doc["only"]:
        if t != "topmount" and (not want or t in want):  # topmount: the approach-1 start's own test
            tests.setdefault(t, []).append(c)
    if want - set(tests):
        raise SystemExit(f"--tests: {', '.join(sorted(want - set(tests)))} not among the case's tests "
                         f"({', '.join(sorted({t for t, _ in stamp_doc['only']} - {'topmount'}))})")
    cfg = entry.load_config(conf)
    design = entry.load_design(start, conf)
    designs = [("start", design)] + [(s, design.with_overrides(o)) for s, o in args.set]
    for row in compare(data, design, conf, cfg, tests, designs):
        print(json.dumps({**row, "start": str(start)}))
    for names in args.truth_off:
        off = truth_off_records(work, args.case, names, stamp_doc, tests)
        for row in compare(off, design, conf, cfg, tests, designs[:1]):
            print(json.dumps({**row, "truth_off": names.split("+"), "start": str(start)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
