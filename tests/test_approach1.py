"""The approach-1 study: the DVC pipeline in the `ci` profile reproduces the
committed reference tables, every fit beats the uncalibrated design, and the
committed `full`-profile calibration recovers the lab's hidden sample."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from conftest import BASELINE, ROOT

REF = ROOT / "tests" / "reference" / "approach1_ci"
TABLE_TOL = 1e-6  # same seeds, same machine class: deterministic; tolerance only for float round-off


def _copy_worktree(dst: Path) -> None:
    """Copy what a clean clone would hold (tracked + unignored files)."""
    files = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"], cwd=ROOT,
                           capture_output=True, text=True, check=True).stdout.split("\0")
    for f in filter(None, files):
        src = ROOT / f
        if src.is_file():
            (dst / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst / f)


def _run(cmd, cwd, env):
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    assert r.returncode == 0, f"{' '.join(cmd)} failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r.stdout + r.stderr


@pytest.fixture(scope="module")
def ci_study(tmp_path_factory):
    """`dvc repro` of the whole pipeline in the ci profile on a fresh copy."""
    repo = tmp_path_factory.mktemp("study")
    _copy_worktree(repo)
    for sub in ("data/measured", "results/approach1/checkpoints"):
        shutil.rmtree(repo / sub, ignore_errors=True)
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    _run(["git", "init", "-q"], repo, env)
    (repo / "params.yaml").write_text((repo / "params.yaml").read_text().replace("profile: full", "profile: ci"))
    # the first run records every file each stage's processes open (tests/tracer/sitecustomize.py)
    trace = _trace_dir(repo)
    trace.mkdir()
    traced = dict(env, DAMPERTWIN_TRACE=str(trace),
                  PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT / "tests" / "tracer"), env.get("PYTHONPATH")])))
    out1 = _run(["dvc", "repro", "-q"], repo, traced)
    out2 = _run(["dvc", "repro"], repo, env)
    status = _run(["dvc", "status"], repo, env)
    return repo, out1, out2, status


def _trace_dir(repo: Path) -> Path:
    return repo.parent / f"{repo.name}_trace"


def _traced_reads(repo: Path) -> dict[str, set[Path]]:
    """stage command (script basename + args) -> project files it read."""
    reads: dict[str, set[Path]] = {}
    skip = (repo / ".dvc", repo / ".git")
    for log in _trace_dir(repo).glob("*.log"):
        for line in log.read_text().splitlines():
            stage, mode, path = line.split("\t")
            p = Path(path)
            if mode != "r" or not p.is_relative_to(repo) or any(p.is_relative_to(s) for s in skip):
                continue
            if "__pycache__" in p.parts or not p.is_file():
                continue
            reads.setdefault(stage, set()).add(p)
    return reads


@pytest.mark.slow  # runs the ci-profile pipeline (minutes)
def test_every_stage_reads_only_declared_deps_params_and_outs(ci_study):
    """DVC wiring is exact: each file a stage's processes opened lies under a
    declared dep, params file or out of that stage (traced in the ci run)."""
    from dvc.repo import Repo

    repo, *_ = ci_study
    reads = _traced_reads(repo)
    allowed = {}
    with Repo(str(repo)) as r:
        for st in r.index.stages:
            argv = st.cmd.split()[1:]
            key = " ".join([Path(argv[0]).name, *argv[1:]])
            allowed[key] = (st.addressing, [Path(d.fs_path) for d in st.deps] + [Path(o.fs_path) for o in st.outs])
    assert set(reads) <= set(allowed), set(reads) - set(allowed)
    assert len(reads) >= 30, sorted(reads)  # every stage ran traced
    problems = []
    for key, files in sorted(reads.items()):
        name, ok = allowed[key]
        for f in sorted(files):
            if not any(f == a or f.is_relative_to(a) for a in ok):
                problems.append(f"{name}: reads {f.relative_to(repo)} (not a declared dep/param/out)")
    assert not problems, "\n".join(problems)


def _numeric_equal(a: pd.DataFrame, b: pd.DataFrame):
    assert list(a.columns) == list(b.columns)
    for c in a.columns:
        if pd.api.types.is_numeric_dtype(a[c]):
            np.testing.assert_allclose(a[c].to_numpy(float), b[c].to_numpy(float), rtol=0, atol=TABLE_TOL, err_msg=c)
        else:
            assert list(a[c]) == list(b[c]), c


@pytest.mark.slow  # runs the ci-profile pipeline (minutes)
def test_ci_profile_reproduces_reference_tables(ci_study):
    repo, *_ = ci_study
    for t in ("table_6_5", "table_6_6"):
        got = pd.read_parquet(repo / "results" / "approach1" / f"{t}.parquet")
        ref = pd.read_parquet(REF / f"{t}.parquet")
        assert len(got) == 10
        _numeric_equal(got, ref)


@pytest.mark.slow  # runs the ci-profile pipeline (minutes)
def test_every_fit_beats_the_uncalibrated_design(ci_study):
    repo, *_ = ci_study
    fits = json.loads((repo / "results" / "approach1" / "fits.json").read_text())
    assert fits["profile"] == "ci"
    assert len(fits["fits"]) == 11  # 8 valves, compliance, 2 top mounts
    for name, f in fits["fits"].items():
        assert f["objective_best"] < f["objective_start"], name
        assert f["objective_polished"] <= f["objective_ga"] * (1 + 1e-12), name  # the polish never loses
        # every fitted value lies in its search interval, and a value on an end of it is listed
        for h in f["bound_hits"]:
            assert h["limit"] == f["bounds"][h["parameter"]][0 if h["bound"] == "lower" else 1], (name, h)
        for k, (lo, hi, _) in f["bounds"].items():
            v = f["values"].get(k, f["nuisance"].get(k))
            assert lo <= v <= hi, (name, k)
            assert (v in (lo, hi)) <= any(h["parameter"] == k for h in f["bound_hits"]), (name, k)


@pytest.mark.slow  # runs the ci-profile pipeline (minutes)
def test_the_part_active_valve_map_is_a_design_input(ci_study, tmp_path):
    """activevalve_map: map.csv is a map a design loads (on the datasheet's grid, other flows), map.json names
    the record relative to the study (same bytes in every clone) and the largest change per map current."""
    from dampertwin.design import load

    repo, *_ = ci_study
    out = repo / "results" / "approach1" / "activevalve"
    doc = json.loads((out / "map.json").read_text())
    assert doc["record"] == "data/measured/activevalve/baseline.parquet" and doc["synthetic"] is True
    base = load(BASELINE)
    assert set(doc["change_from_datasheet"]) == {f"{c:g}" for c in base.pq_map.currents}
    shutil.copy(out / "map.csv", tmp_path / "own.csv")
    base.dump(tmp_path / "d.yaml")
    own = load(tmp_path / "d.yaml", map_dirs=[BASELINE.parent]).with_overrides({"active_valve.pq_map": "own.csv"})
    assert np.array_equal(own.pq_map.dps, base.pq_map.dps) and not np.array_equal(own.pq_map.flow, base.pq_map.flow)
    assert (out / "pq.png").stat().st_size > 10_000


@pytest.mark.slow  # runs the ci-profile pipeline (minutes)
def test_the_study_fits_and_designs_use_the_parts_active_valve_map(ci_study):
    """params.yaml valve_map: part (the default): the compliance fit ran on the design with the part's map
    (its design hash), the assembled designs of the datasheet map's cases carry the part's map (a copy beside
    the design, which it names: the file loads on its own), the different-active-valve case keeps its
    variant's map."""
    from dampertwin.design import load
    from dampertwin.io import read_meta

    repo, *_ = ci_study
    a1 = repo / "results" / "approach1"
    base = load(BASELINE)
    part = load(BASELINE, map_dirs=[a1 / "activevalve"]).with_overrides(
        {"active_valve.pq_map": str(a1 / "activevalve" / "map.csv")})
    assert part.pq_map != base.pq_map
    for case in ("baseline_1.6", "lower_piston_intake"):
        d = load(a1 / "designs" / f"{case}.yaml")
        assert d.pq_map == part.pq_map, case
        assert d["active_valve.pq_map"] == f"{case}_active_valve.csv", case
        src = d.param("active_valve.pq_map").source
        assert src.startswith("measured: the part on its active-valve bench"), case
        assert src.endswith("; a copy of results/approach1/activevalve/map.csv"), (case, src)
    alt = load(a1 / "designs" / "different_active_valve.yaml")
    assert alt.pq_map == base.with_overrides({"active_valve.pq_map": "active_valve_alternative.csv"}).pq_map
    # the copy names the file it copies (the variant's valve), not the baseline's datasheet map
    assert alt.param("active_valve.pq_map").source == ("conf/variant/different_active_valve.yaml: the case's own "
                                                        "active valve; a copy of conf/design/active_valve_alternative.csv")
    valves = {}
    for v in ("piston_rebound", "piston_intake", "base_compression", "base_intake"):
        valves.update(yaml.safe_load((a1 / "valves" / v / "overlay.yaml").read_text())["overrides"])
    fitted_on = read_meta(a1 / "compliance" / "history.parquet")["design_hash"]
    assert fitted_on == part.with_overrides(valves).hash() != base.with_overrides(valves).hash()


@pytest.mark.slow  # runs the ci-profile pipeline (minutes)
def test_lab_regenerates_the_committed_data_bit_for_bit(ci_study):
    """The copy ran `dvc repro` without data/measured: the lab stage it ran
    must give the output hash committed in dvc.lock (deterministic lab, and
    a dvc.lock that is not stale after a code change)."""
    repo, *_ = ci_study

    def lab_out(lock):
        (out,) = yaml.safe_load(lock.read_text())["stages"]["lab"]["outs"]
        return out["path"], out["md5"]

    assert lab_out(repo / "dvc.lock") == lab_out(ROOT / "dvc.lock")


@pytest.mark.slow  # runs the ci-profile pipeline (minutes)
def test_second_repro_does_nothing_and_status_is_clean(ci_study):
    _, _, out2, status = ci_study
    assert "Running stage" not in out2
    assert "up to date" in status.lower() or status.strip() == ""


@pytest.mark.slow  # runs the ci-profile pipeline (minutes)
def test_tables_and_plots_are_written(ci_study):
    repo, *_ = ci_study
    a1 = repo / "results" / "approach1"
    assert (a1 / "table_6_5.md").read_text().startswith("Table 6.5")
    metrics = json.loads((a1 / "metrics.json").read_text())
    assert set(metrics) == {f"{h} {e} diff [%]" for h in ("Rebound", "Compression") for e in ("max", "min")} | {
        "200 Hz diff [dB]", "300 Hz diff [dB]", "flags", "code_hash"}
    assert metrics["flags"]["count"] == len(metrics["flags"]["cells"])
    assert "Definition:" in (a1 / "table_6_5.md").read_text()
    for fit in ("valves/piston_rebound", "topmount/baseline", "compliance"):
        unc = json.loads((a1 / fit / "uncertainty.json").read_text())
        assert {p["parameter"] for p in unc["parameters"]} >= set(
            json.loads((a1 / "fits.json").read_text())["fits"][fit]["values"]) - {"top_mount.F_LD"}
        assert (a1 / fit / "uncertainty.md").read_text().startswith("# Identifiability and uncertainty")
    trend = json.loads((repo / "results" / "sweeps" / "metrics.json").read_text())["table65_trend_agreement"]
    assert trend["compared"] > 0 and len(trend["disagreeing"]) == trend["compared"] - trend["agree"]
    for case in ("baseline_1.6", "lower_base_intake"):
        assert (a1 / "plots" / case / "monosine.png").stat().st_size > 10_000
        assert (a1 / "plots" / case / "psd.png").stat().st_size > 10_000
    assert (a1 / "plots" / "baseline_1.6" / "curving.png").is_file()
    assert (a1 / "valves" / "piston_rebound" / "pq.png").is_file()
    hist = pd.read_parquet(a1 / "valves" / "piston_rebound" / "history.parquet")
    from dampertwin.calibration.approach1 import valve_objective_name
    from dampertwin.design import yaml_load_file

    best = f"best [{valve_objective_name(yaml_load_file(repo / 'conf' / 'calibration' / 'valves.yaml'))[1]}]"
    assert hist[best].is_monotonic_decreasing or (np.diff(hist[best]) <= 1e-9).all()
