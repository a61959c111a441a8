"""DVC stage `discrepancy` (issue 11): the discrepancy workflow on the
approach-1 calibrated baseline design (results/approach1/designs/
baseline_1.6.yaml, written by assemble) and the measured folder (params.yaml
`measured`) -> results/discrepancy/ (verdict.json, design.yaml, report.md,
plots/). The measured folder's active-valve bench record gives the design the
part's own P/Q map first (entry.part_valve_map: active_valve_part.csv beside
design.yaml), as `dampertwin discrepancy` does by default, whatever params.yaml
`valve_map` says. It reads the measured tests it declares (READS), not a
user's dyno exports, which `dampertwin discrepancy` reads. The profile (params.yaml `profile`) names the workflow's budget
(its `discrepancy:` key, a profile of conf/discrepancy.yaml); the seed is conf/config.yaml `seed`."""

import os

from _common import CONF, OUT, ROOT, config, measured_dir, stage
from dampertwin.discrepancy.entry import load_config
from dampertwin.discrepancy.entry import main as discrepancy

# The measured tests this stage reads: its ${measured}/<test> deps in dvc.yaml (tests/test_reliability_runs.py). A test
# the profile also reads from a user's folder (dyno exports) is `dampertwin discrepancy`'s, not the stage's: a
# stage reads only what it declares, and DVC cannot declare a folder that may not exist.
READS = ("flowbench", "compliance", "curving", "monosine", "random", "thermal", "friction")


def main() -> None:
    cfg = config()  # the profile's `scheduler:` (a Dask address) runs the records on that cluster
    os.chdir(ROOT)  # paths relative to the repository: the report names no machine's folders (same bytes anywhere)
    rel = lambda p: os.path.relpath(p, ROOT)  # noqa: E731
    profile = cfg.profile.get("discrepancy", cfg.profile.name)
    wanted = load_config(CONF)["profiles"].get(profile, {}).get("tests") or {}
    left = sorted(t for t in wanted if t not in READS and (measured_dir() / t).is_dir())
    if left:
        print(f"discrepancy: {', '.join(rel(measured_dir() / t) for t in left)} not read by this stage "
              f"(run `dampertwin discrepancy` on the folder to use them)")
    doc = discrepancy(rel(OUT / "designs" / "baseline_1.6.yaml"), rel(measured_dir()), rel(ROOT / "results" / "discrepancy"),
                      profile=profile, seed=int(cfg.seed), scheduler=cfg.profile.scheduler,
                      tests={t: c for t, c in wanted.items() if t in READS})
    print(f"discrepancy: verdict {doc['verdict']} {', '.join(doc['effects'])}; held-out gap "
          f"{doc['gap']['before']:.3g} -> {doc['gap']['after']:.3g}")


if __name__ == "__main__":
    stage(main, "discrepancy")
