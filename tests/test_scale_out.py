"""Scale-out on a Dask cluster (issue 39, item 6): the heavy commands take a
scheduler address and give the same bytes as the local run -- approach 2's
sensitivity runs, the discrepancy workflow's records, a sweep's variants
and the hidden-effect bench matrix's cases
(the GA and concurrent-GA evaluators: tests/test_ga.py,
tests/test_concurrent_ga.py) -- each against a 2-worker
``distributed.LocalCluster``; the SLURM cluster description
(conf/cluster/slurm.yaml) is checked without a SLURM cluster."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from dampertwin.errors import UserError
from dampertwin.parallel import CLUSTER_KEYS, check_cluster_config, slurm_cluster

from test_discrepancy import DESIGN, TESTS  # the fixtures short_training, control, control_serial_run: conftest.py

ROOT = Path(__file__).resolve().parents[1]
SLURM = ROOT / "conf" / "cluster" / "slurm.yaml"

distributed = pytest.importorskip("distributed")  # a dev dependency


def cluster(processes: bool = False):
    return distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=processes, dashboard_address=None)


def executed(lc) -> int:
    """Tasks the cluster's workers ran (0 would mean the work stayed local)."""
    return sum(w.state.executed_count for w in lc.workers.values())


def test_approach2_sensitivity_on_a_cluster_gives_the_same_bytes(short_training):
    from dampertwin.calibration import approach2 as a2
    from dampertwin.design import load, yaml_load_file

    design = load(ROOT / "conf" / "design" / "baseline.yaml")
    cal = yaml_load_file(ROOT / "conf" / "calibration" / "approach2.yaml")
    rec = a2.check_damper_record(short_training, "training", ["I1.6"])
    st = a2.SensitivitySettings.from_config(cal["sensitivity"], n_base=2)
    kw = dict(seed=4, bandwidth=1000.0, max_wall_s=120, progress=False, batch=6)  # 20 runs: 4 batches
    _, local, Y = a2.sensitivity(design, rec, cal, st, **kw)
    with cluster() as lc:
        _, remote, Yc = a2.sensitivity(design, rec, cal, st, scheduler=lc.scheduler_address, **kw)
        assert executed(lc) == 4  # one task per batch
    assert np.isfinite(Y).all() and Y.shape[0] == 20
    assert Yc.tobytes() == Y.tobytes()
    assert remote.S1.tobytes() == local.S1.tobytes() and remote.S1_conf.tobytes() == local.S1_conf.tobytes()
    assert remote.meta == local.meta


def test_approach2_fit_on_a_cluster_gives_the_same_fit(short_training):
    from dampertwin.calibration import approach2 as a2
    from dampertwin.calibration.ga import GASettings
    from dampertwin.design import load, yaml_load_file

    design = load(ROOT / "conf" / "design" / "baseline.yaml")
    cal = yaml_load_file(ROOT / "conf" / "calibration" / "approach2.yaml")
    rec = a2.check_damper_record(short_training, "training", ["I1.6"])
    W = np.ones((len(a2.VALVES), sum(len(c[1]) for c in a2.damper_cases(rec, float(cal["input_cutoff"])))))
    s = GASettings(population=4, reproduction_ratio=75, generations=1, mutation_probability=10, max_wall_s=120)
    kw = dict(seed=5, bandwidth=1000.0, progress=False)
    local, _ = a2.fit(design, rec, cal, W, list(a2.VALVES), s, **kw)
    with cluster() as lc:
        remote, _ = a2.fit(design, rec, cal, W, list(a2.VALVES), s, scheduler=lc.scheduler_address, **kw)
        assert executed(lc) >= 2
    assert remote.best == local.best and remote.best_group_objectives == local.best_group_objectives
    assert remote.history.equals(local.history)


def test_eq_7_1_integrals_do_not_depend_on_the_batch():
    """A member scored alone, in a chunk or in the whole population: the same bits (a matrix product's
    blocking depends on the batch size and once changed the last digit on a cluster)."""
    from dampertwin.calibration import sensitivity as sens

    rng = np.random.default_rng(0)
    R, W, q = np.abs(rng.standard_normal((50, 20001))), rng.uniform(0, 1, (4, 20001)), rng.uniform(0, 1e-3, 20001)
    full = sens.weighted_integrals(R, q, W)
    assert full == pytest.approx(R @ (W * q).T, rel=1e-12)
    for lo, k in ((0, 1), (5, 2), (10, 7), (20, 13)):
        assert sens.weighted_integrals(R[lo:lo + k], q, W).tobytes() == full[lo:lo + k].tobytes()
        assert sens.row_integrals(R[lo:lo + k], q).tobytes() == sens.row_integrals(R, q)[lo:lo + k].tobytes()


def test_approach1_objective_does_not_depend_on_the_batch():
    """The GA objective of the study's fits (eq. 6.x, calibration.polish.Records): a member's value is the
    same bits whichever chunk of its population a cluster worker scores."""
    from dampertwin.calibration.polish import Records

    rng = np.random.default_rng(1)
    X = rng.uniform(0, 1, (30, 3))
    basis = rng.standard_normal((3, 8001))
    # the stand-in simulation is row by row like the real one (a matmul's rounding depends on the
    # batch's shape on some BLAS kernels: AVX-512 machines gave other last bits for 1 row than for 30)
    rec = Records(lambda P: np.sin(sum(P[:, j, None] * basis[j] for j in range(3))), rng.uniform(0, 1e-3, 8001))
    full = rec.scores(X)[0]
    assert full == pytest.approx(np.abs(np.sin(X @ basis)) @ rec.weights, rel=1e-12)
    for lo, k in ((0, 1), (3, 2), (7, 8), (15, 15)):
        assert rec.scores(X[lo:lo + k])[0].tobytes() == full[lo:lo + k].tobytes()


def test_discrepancy_workflow_on_a_cluster_gives_the_same_bytes(control, control_serial_run, tmp_path):
    from dampertwin.discrepancy import entry

    with cluster() as lc:
        a = entry.main(str(DESIGN), str(control), str(tmp_path / "cluster"), profile="ci", seed=0, progress=False,
                       tests=TESTS, scheduler=lc.scheduler_address)
        assert executed(lc) >= 3 and not lc.scheduler.tasks  # record tasks ran there, all released
    local, b = control_serial_run  # the same call with workers=1, run once for the suite
    assert a == b
    for name in ("verdict.json", "resolvability.json", "design.yaml", "report.md"):
        assert (tmp_path / "cluster" / name).read_bytes() == (local / name).read_bytes(), name


def test_fit_command_on_a_cluster_gives_the_same_fit(tmp_path):
    """``dampertwin fit --scheduler``: the GA's populations on the cluster, the same fit.json."""
    from dampertwin.cli import main
    from test_fitting import _top_mount_record

    rec = _top_mount_record(tmp_path, 0.0, {})
    args = ["fit", "topmount", "--data", str(rec), "--param", "k0=6e5:2.4e6:log", "--population", "6",
            "--generations", "2"]
    with cluster() as lc:
        assert main([*args, "--out", str(tmp_path / "cluster"), "--scheduler", lc.scheduler_address]) == 0
        assert executed(lc) >= 2
    assert main([*args, "--out", str(tmp_path / "local")]) == 0
    a, b = (json.loads((tmp_path / f / "fit.json").read_text()) for f in ("cluster", "local"))
    assert a == b


def _sweep(results: Path, *extra: str) -> None:
    cmd = [sys.executable, "-m", "dampertwin.cli", "sweep", *extra, f"results_dir={results}", "sweep=t",
           "tests=[monosine]", "use_calibrated=false", "variant=baseline_1.6,lower_base_intake"]
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-4000:]


def _files(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and ".hydra" not in p.parts}


@pytest.mark.slow  # two Hydra multiruns of two variants: 27-53 s on the 2-core machine
def test_sweep_on_a_cluster_gives_the_same_bytes(tmp_path):
    runs = tmp_path / "sweeps"  # one results_dir for both (it is in the artifacts' metadata)
    with cluster(processes=True) as lc:  # Hydra's job state is per process: process workers
        _sweep(runs, "--scheduler", lc.scheduler_address)
        assert sum(p.all_durations.get("compute", 0) for p in lc.scheduler.task_prefixes.values()) > 0  # ran there
    runs.rename(tmp_path / "cluster")
    _sweep(runs)
    runs.rename(tmp_path / "local")
    a, b = _files(tmp_path / "cluster" / "t"), _files(tmp_path / "local" / "t")
    assert {"baseline_1.6/monosine.parquet", "lower_base_intake/kpis.parquet", "summary.parquet"} <= set(a)
    assert a.keys() == b.keys() and all(a[k] == b[k] for k in a), [k for k in a if a[k] != b.get(k)]


def test_an_unreachable_scheduler_is_a_clear_error():
    import dask

    from dampertwin.parallel import DaskMap

    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        with pytest.raises(UserError, match=r"scheduler 'tcp://127.0.0.1:9': no Dask scheduler reached"):
            DaskMap("tcp://127.0.0.1:9")(abs, [1])


def test_dask_launcher_needs_a_scheduler_address():
    from hydra_plugins.dampertwin_dask_launcher.dask_launcher import DaskLauncher

    for bad in ({}, {"scheduler": ""}, {"scheduler": "tcp://h:1", "backend": "loky"}):
        with pytest.raises(UserError, match=r"conf/hydra/launcher/dask\.yaml: (scheduler|unknown key)"):
            DaskLauncher(**bad)
    launcher = yaml.safe_load((ROOT / "conf" / "hydra" / "launcher" / "dask.yaml").read_text())
    assert launcher["_target_"].endswith(".DaskLauncher") and set(launcher) == {"_target_", "scheduler"}


# ------------------------------------------------------------ the SLURM cluster description
def test_shipped_slurm_description_is_valid():
    doc = yaml.safe_load(SLURM.read_text())
    assert check_cluster_config(doc, str(SLURM)) == doc
    assert set(doc) == set(CLUSTER_KEYS)  # every key documented in the shipped file


@pytest.mark.parametrize("key, value, why", [
    ("cores", 0, "cores: 0; expected cores per SLURM job"),
    ("cores", "2", "cores: '2'; expected"),
    ("memory", 4, "memory: 4; expected memory per SLURM job"),
    ("memory", "4 gigs", "memory: '4 gigs'"),
    ("walltime", "2h", "walltime: '2h'; expected wall-time limit"),
    ("jobs", True, "jobs: True; expected SLURM jobs"),
    ("queue", 3, "queue: 3; expected SLURM partition"),
    ("job_extra_directives", "--exclusive", "job_extra_directives"),
    ("partition", "long", "unknown key 'partition'"),
    ("jobs", None, "missing key 'jobs'"),
])
def test_bad_slurm_description_names_file_and_key(key, value, why):
    doc = yaml.safe_load(SLURM.read_text())
    if value is None:
        del doc[key]
    else:
        doc[key] = value
    with pytest.raises(UserError) as ei:
        check_cluster_config(doc, "conf/cluster/x.yaml")
    assert "conf/cluster/x.yaml: " in str(ei.value) and why in str(ei.value)
    with pytest.raises(UserError, match="expected a mapping"):
        check_cluster_config([doc], "conf/cluster/x.yaml")


def test_slurm_job_script_from_the_description():
    pytest.importorskip("dask_jobqueue")
    doc = {**yaml.safe_load(SLURM.read_text()), "queue": "long", "job_extra_directives": ["--exclusive"]}
    c = slurm_cluster(doc, str(SLURM))
    try:
        script = c.job_script()
    finally:
        c.close()
    for line in ("#SBATCH -p long", "#SBATCH --cpus-per-task=2", "#SBATCH --mem=4G", "#SBATCH -t 02:00:00",
                 "#SBATCH --exclusive", "--nworkers 2"):
        assert line in script, (line, script)


def test_slurm_without_dask_jobqueue_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "dask_jobqueue", None)  # import fails
    with pytest.raises(UserError, match=r"conf/cluster/slurm\.yaml: a SLURM cluster needs dask-jobqueue.*\.\[slurm\]"):
        slurm_cluster(yaml.safe_load(SLURM.read_text()), "conf/cluster/slurm.yaml")


def test_cluster_command_checks_the_description(tmp_path, capsys):
    from dampertwin.cli import main

    bad = tmp_path / "slurm.yaml"
    bad.write_text("cores: 2\nmemory: 4GB\nwalltime: '01:00:00'\njobs: 0\n")
    assert main(["cluster", "--config", str(bad), "--check"]) == 2
    assert f"{bad}: jobs: 0" in capsys.readouterr().err
    assert main(["cluster", "--config", str(tmp_path / "none.yaml"), "--check"]) == 2
    assert "cluster description not found" in capsys.readouterr().err
    # a directive or value with a line break would add a shell line of its own to the job script
    for extra in ("job_extra_directives: [\"--exclusive\\nrm -rf $HOME\"]\n", "job_extra_directives: [exclusive]\n",
                  "account: \"me\\necho x\"\n"):
        bad.write_text("cores: 2\nmemory: 4GB\nwalltime: '01:00:00'\njobs: 1\n" + extra)
        assert main(["cluster", "--config", str(bad), "--check"]) == 2
        err = capsys.readouterr().err
        assert f"{bad}: {extra.split(':')[0]}:" in err and "Traceback" not in err, err
    if importlib.util.find_spec("dask_jobqueue"):  # with it, the job script; without, test_slurm_without_...
        assert main(["cluster", "--config", str(SLURM), "--check"]) == 0
        assert "#SBATCH --mem=4G" in capsys.readouterr().out


# ------------------------------------------------------------ the bench matrix
_TIMING = ("lab_s", "lab_reused", "start_s", "case_s", "wall_s_per_case")


def _matrix(work: Path, *extra: str) -> tuple[dict, list]:
    """bench/discrepancy.py on one control case (nominal start, three records), as a user runs it:
    (the summary line without timings, the case rows without timings)."""
    cmd = [sys.executable, str(ROOT / "bench" / "discrepancy.py"), "--controls", "1", "--per-effect", "0",
           "--pairs", "0", "--artefacts", "0", "--start", "nominal", "--seed", "3", "--work", str(work),
           "--tests", "compliance:baseline,monosine:baseline_1.6,monosine:baseline_0.32", *extra]
    env = dict(os.environ, MPLBACKEND="Agg")
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-4000:]
    drop = lambda d: {k: v for k, v in d.items() if k not in _TIMING}  # noqa: E731
    rows = [drop(json.loads(x)) for x in r.stderr.splitlines() if x.startswith("{")]
    return drop(json.loads(r.stdout.strip().splitlines()[-1])), rows


@pytest.mark.slow  # one control case twice (lab records once, the workflow twice): ~2-3 min on 2 cores
def test_bench_matrix_on_a_cluster_gives_the_same_rows(tmp_path):
    """``bench/discrepancy.py --scheduler``: the cases run as tasks there, the same rows and summary
    as the local run (the lab records of the first run are reused by the second: same stamp)."""
    work = tmp_path / "work"
    with cluster(processes=True) as lc:  # the script's own case function, shipped to process workers
        remote = _matrix(work, "--scheduler", lc.scheduler_address)
        assert sum(p.all_durations.get("compute", 0) for p in lc.scheduler.task_prefixes.values()) > 0  # ran there
    (work / "out0").rename(tmp_path / "remote_out")
    local = _matrix(work)
    assert len(local[1]) == 1 and local[1][0]["cell"] == "control" and local[1][0]["verdict"]
    assert remote == local
    a, b = _files(tmp_path / "remote_out"), _files(work / "out0")  # the case's workflow output, every file
    assert {"verdict.json", "design.yaml", "report.md"} <= set(a)
    assert a.keys() == b.keys() and all(a[k] == b[k] for k in a), [k for k in a if a[k] != b.get(k)]
