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

A start design written by another checkout names its P/Q map relative to that checkout's
conf/design: give that folder in DAMPERTWIN_MAP_DIRS.
"""

from __future__ import annotations

import argparse
import json
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
            raise SystemExit(f"--set: {item!r}; expected key=value")
        out[key.strip()] = yaml.safe_load(val)
    return out


def by_test(problem: Problem, z: np.ndarray) -> dict:
    """Mean z^2 per feature of each test / case."""
    rec = np.array(["/".join(lab[:2]) for lab in problem.labels])
    return {r: round(float(np.mean(z[rec == r] ** 2)), 2) for r in sorted(set(rec))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", required=True, help="a bench/discrepancy.py --work folder")
    ap.add_argument("--case", type=int, required=True, help="the case number K (caseK/, startK/)")
    ap.add_argument("--set", action="append", default=[], help="a further design: key=value[,key=value...]")
    args = ap.parse_args(argv)
    work, conf = Path(args.work), ROOT / "conf"
    data = work / f"case{args.case}"
    stamp = data / ".case.json"
    if not stamp.is_file():
        raise SystemExit(f"{data}: no finished case (its .case.json stamp is missing)")
    start = work / f"start{args.case}" / "start_design.yaml"
    start = start if start.is_file() else conf / "design" / "baseline.yaml"
    tests: dict = {}
    for t, c in json.loads(stamp.read_text())["only"]:
        if t != "topmount":  # the approach-1 start's own test, not one the workflow reads
            tests.setdefault(t, []).append(c)
    cfg = entry.load_config(conf)
    design = entry.load_design(start, conf)
    units, variants, _ = entry.read_units(data, design, conf, cfg["features"], cfg["profiles"]["ci"], tests)
    problem = Problem(units, cfg["features"], variants, progress=False)
    designs = [("start", design)] + [(s, design.with_overrides(overrides(s))) for s in args.set]
    rows = [problem.simulate([d])[0] for _, d in designs]  # one at a time: a batch shares one P/Q map
    problem.set_noise(rows[0])
    for (name, _), row in zip(designs, rows):
        z = problem.z(row)
        if not np.all(np.isfinite(z)):
            raise SystemExit(f"{name}: a record failed to simulate: {problem.failures[-1:]}")
        print(json.dumps({"design": name, "start": str(start), "gap": round(float(np.sqrt(np.mean(z * z))), 3),
                          "mean_z2_by_test": by_test(problem, z)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
