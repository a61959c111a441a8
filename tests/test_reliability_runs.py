"""Issue 13, reliability, the runs: a bad measurement is rejected naming the file and column; a failed GA
member is infeasible with its reason; stages and the CLI print one line and exit 2; no partial artifacts;
sweeps (the design inputs: tests/test_reliability.py). Each case failed on the old behaviour."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dampertwin.design import load
from dampertwin.errors import UserError
from dampertwin.io import DataError, read_frame, write_frame

from conftest import BASELINE, ROOT

CONF = ROOT / "conf"
PY = sys.executable


# ------------------------------------------------------------ measurements
def mono(n=20_000, fs=50_000.0, **cols):
    t = np.arange(n) / fs
    df = pd.DataFrame({"time [s]": t, "displacement [m]": 0.005 * np.sin(2 * math.pi * 13 * t),
                       "force [N]": 100 * np.sin(2 * math.pi * 13 * t), "rod acceleration [m/s^2]": np.zeros(n),
                       "current [A]": 1.6})
    for k, v in cols.items():
        df[k] = v
    return df


def frame_rejected(tmp: Path, df: pd.DataFrame, protocol, *needles, suffix=".parquet", **kw) -> str:
    p = tmp / f"m{suffix}"
    if suffix == ".csv":
        df.to_csv(p, index=False)
    else:
        write_frame(p, df, {})
    with pytest.raises(DataError) as ei:
        read_frame(p, protocol, **kw)
    msg = str(ei.value)
    assert str(p) in msg, msg
    for n in needles:
        assert n in msg, msg
    return msg


def _stretched(k):
    df = mono()
    df["time [s]"] *= k
    return df


def _decimated():
    df = mono(n=200_000)
    return df.iloc[::500].reset_index(drop=True)  # 100 Hz


def _two_runs_nan_label():
    a, b = mono().assign(run="I1.6"), mono().assign(run=None)
    return pd.concat([a, b], ignore_index=True)


FRAME_CASES = {
    "string column of an unknown quantity": (lambda: mono(**{"comment [-]": "ok"}), "monosine", {},
                                             "'comment [-]' is not numeric"),
    "non-SI unit of an unknown quantity": (lambda: mono(**{"pressure [bar]": 1.0}), "monosine", {},
                                           "unit 'bar' is not SI"),
    "non-SI millimetres": (lambda: mono(**{"stroke [mm]": 0.0}), "monosine", {}, "unit 'mm' is not SI"),
    "non-SI litres per minute": (lambda: mono(**{"leak [l/min]": 0.0}), "monosine", {}, "unit 'l/min' is not SI"),
    "two columns of one quantity": (lambda: mono(**{"force  [N]": 0.0}), "monosine", {}, "hold the same quantity 'force'"),
    "NaN run labels": (_two_runs_nan_label, "monosine", {}, "missing (NaN) labels"),
    "boolean column": (lambda: mono(**{"flag [-]": True}), "monosine", {}, "'flag [-]' is not numeric"),
    "decimated to 100 Hz": (_decimated, "monosine", {"rate": 50_000.0}, "sampling rate 100 Hz; protocol monosine records at 50000 Hz"),
    "time-stretched x10": (lambda: _stretched(10.0), "monosine", {"rate": 50_000.0}, "sampling rate 5000 Hz"),
    "all-zero force": (lambda: mono(**{"force [N]": 0.0}), "monosine", {}, "'force [N]' is constant (0.0)"),
    "constant displacement": (lambda: mono(**{"displacement [m]": 0.001}), "monosine", {}, "'displacement [m]' is constant"),
    "empty record": (lambda: mono().iloc[:0], "monosine", {}, "no rows"),
}


@pytest.mark.parametrize("case", FRAME_CASES, ids=list(FRAME_CASES))
def test_bad_measurement_rejected_naming_file_and_column(tmp_path, case):
    make, protocol, kw, needle = FRAME_CASES[case]
    frame_rejected(tmp_path, make(), protocol, needle, **kw)


def test_csv_string_column_is_a_clean_error(tmp_path):
    frame_rejected(tmp_path, mono(**{"comment [-]": "text"}), "monosine", "not numeric", suffix=".csv")


def test_all_zero_flowbench_record_rejected_before_any_fit():
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        t = np.arange(3000) / 1000.0
        df = pd.DataFrame({"run": "piston_rebound", "time [s]": t, "flow [m^3/s]": 0.0, "dp [Pa]": 0.0})
        p = write_frame(Path(d) / "fb.parquet", df, {})
        with pytest.raises(DataError, match="constant"):
            read_frame(p, "flowbench", rate=1000.0)


def test_recording_rates_follow_the_protocols():
    from dampertwin.protocols import load_protocol, recording_rates

    assert recording_rates(load_protocol(CONF / "test" / "monosine.yaml")) == 50_000.0
    tm = recording_rates(load_protocol(CONF / "test" / "topmount.yaml"))
    assert tm["static"] == 200.0 and tm["random"] == 5000.0


# ------------------------------------------------------------ GA layer
class _FakeBatch:
    """Stand-in for simulate_batch: a member with piston_rebound.a > 1000
    raises (as the solver did for bad members), others return a ramp."""

    def __init__(self, n_out=None):
        self.calls, self.n_out = [], n_out

    def __call__(self, designs, ex, configuration, *, rate, duration, channels, max_wall_s=None, **kw):
        self.calls.append({"n": len(designs), "max_wall_s": max_wall_s})
        if any(d["piston_rebound.a"] > 1000 for d in designs):
            raise SystemError("returned a result with an exception set")
        n = self.n_out or int(round(duration * rate)) + 1
        out = np.vstack([np.full(n, d["piston_rebound.a"]) for d in designs])
        return np.arange(n) / rate, {c: out for c in channels}, np.zeros(len(designs), int)


def _objective(monkeypatch, fake, wall=42.0):
    from dampertwin.calibration import approach1
    from dampertwin.calibration.ga import ParamSpec

    monkeypatch.setattr(approach1, "simulate_batch", fake)
    d = load(BASELINE)
    specs = [ParamSpec("piston_rebound.a", 0.0, 5000.0), ParamSpec("piston_rebound.b", -1.0, 1e5)]
    t = np.arange(11) / 10.0
    ch = approach1.Channel(("p upstream [Pa]",), lambda c, nuis: c["p upstream [Pa]"])
    return approach1._batch_objective(d, specs, [(t, np.zeros(11), None, {})], "valve", ch, wall)


def test_failed_members_are_infeasible_with_reason_and_the_rest_scored(monkeypatch):
    fake = _FakeBatch()
    f = _objective(monkeypatch, fake)
    X = np.array([[300.0, 4000.0], [2000.0, 4000.0], [300.0, -1.0], [400.0, 4000.0]])
    J, reasons = f(X)
    assert np.isfinite(J[[0, 3]]).all() and J[3] > J[0]
    assert np.isnan(J[1]) and "SystemError" in reasons[1]           # simulation raised: only this member lost
    assert np.isnan(J[2]) and "no. 49 (piston_rebound.b)" in reasons[2]  # invalid design, never simulated
    assert reasons[0] is None and reasons[3] is None
    assert all(c["max_wall_s"] == 42.0 for c in fake.calls)         # every batch carries the wall-time cap


def test_short_simulation_is_an_error_not_a_silent_truncation(monkeypatch):
    f = _objective(monkeypatch, _FakeBatch(n_out=5))
    with pytest.raises(ValueError, match="no truncation"):
        f(np.array([[300.0, 4000.0]]))


def test_ga_counts_failure_reasons_and_refuses_an_all_infeasible_fit():
    from dampertwin.calibration.ga import Evaluator, FitError, GASettings, ParamSpec, run_ga

    specs = [ParamSpec("x", -1.0, 1.0)]
    s = GASettings(population=6, reproduction_ratio=80, generations=2, mutation_probability=10)

    def half(X):
        bad = X[:, 0] > 0
        return np.where(bad, np.nan, X[:, 0] ** 2), ["x > 0 not allowed" if b else None for b in bad]

    res = run_ga(specs, Evaluator(half), s, seed=1, progress=False)
    assert res.failed > 0 and res.failures == {"x > 0 not allowed": res.failed} and res.best["x"] <= 0
    with pytest.raises(FitError, match="every simulation of the fit failed"):
        run_ga(specs, Evaluator(lambda X: (np.full(len(X), np.nan), ["boom"] * len(X))), s, seed=1, progress=False)


def test_every_profile_caps_the_wall_time_of_ga_batches():
    from dampertwin.calibration.ga import GASettings
    from dampertwin.design import yaml_load_file

    for f in sorted((CONF / "profile").glob("*.yaml")):
        for block, c in yaml_load_file(f)["ga"].items():
            assert GASettings.from_config(c).max_wall_s > 0, (f, block)
    with pytest.raises(UserError, match="max_wall_s"):
        GASettings.from_config({"population": 4, "reproduction_ratio": 80, "generations": 1,
                                "mutation_probability": 10})


# ------------------------------------------------------------ stages, CLI, artifacts
def _stage(*args, env=None):
    return subprocess.run([PY, *args], cwd=ROOT, capture_output=True, text=True,
                          env=dict(os.environ, MPLBACKEND="Agg", **(env or {})), timeout=300)


@pytest.mark.parametrize("args, needle", [
    (["stages/flowbench_fit.py", "no_such_valve"], "unknown valve design 'no_such_valve'"),
    (["stages/topmount_fit.py", "no_such_mount"], "unknown top mount 'no_such_mount'"),
    (["stages/assemble.py", "no_such_case"], "no_such_case.yaml: cannot read"),
])
def test_stage_user_error_is_one_line_and_exit_2(args, needle):
    r = _stage(*args)
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in r.stderr, r.stderr
    dbg = _stage(*args, env={"DAMPERTWIN_DEBUG": "1"})
    assert dbg.returncode == 2 and "Traceback" in dbg.stderr


def test_cli_user_error_is_one_line_and_exit_2(tmp_path, capsys):
    from dampertwin.cli import main

    bad = tmp_path / "x.yaml"
    bad.write_bytes(b"\xff\xfe\x00binary")
    conf = tmp_path / "conf"
    shutil.copytree(CONF / "variant", conf / "variant")
    (conf / "variant" / "baseline_1.6.yaml").write_bytes(b"\x00\x01")
    assert main(["plot", "baseline_1.6", "--conf", str(conf), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "baseline_1.6.yaml" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_fit_outputs_are_all_or_nothing(tmp_path):
    sys.path.insert(0, str(ROOT / "stages"))
    try:
        from _common import staged_dir
    finally:
        sys.path.pop(0)
    out = tmp_path / "valves" / "v"
    with pytest.raises(ZeroDivisionError):
        with staged_dir(out) as tmp:
            (tmp / "overlay.yaml").write_text("overrides: {}\n")
            (tmp / "history.parquet").write_bytes(b"x")
            1 / 0  # a failure after the first artifacts
    assert not out.exists() and list(out.parent.iterdir()) == []
    (out.parent / ".v.tmpKILLED").mkdir()  # a SIGKILLed run's leftover is removed by the next run
    with staged_dir(out) as tmp:
        (tmp / "overlay.yaml").write_text("overrides: {}\n")
    assert sorted(p.name for p in out.parent.iterdir()) == ["v"] and (out / "overlay.yaml").is_file()


def test_write_fit_with_a_zero_start_objective_does_not_divide_by_zero(tmp_path):
    sys.path.insert(0, str(ROOT / "stages"))
    try:
        from _common import write_fit
    finally:
        sys.path.pop(0)
    from dampertwin.calibration.ga import FitResult

    res = FitResult({"piston_rebound.a": 1.0}, 0.0, 0.0, pd.DataFrame({"generation": [0], "best": [0.0],
                                                                        "mean": [0.0], "failed": [0]}), 0, 1)
    write_fit(tmp_path, res, {"fit": "t"}, "Pa*s", "h")
    assert json.loads((tmp_path / "metrics.json").read_text())["improvement_pct"] is None


# ------------------------------------------------------------ sweeps
def _project_copy(tmp: Path) -> Path:
    proj = tmp / "proj"
    shutil.copytree(CONF, proj / "conf")
    for f in ("dvc.yaml", "pyproject.toml"):
        shutil.copy(ROOT / f, proj / f)
    return proj


def _sweep(cwd: Path, *args: str, env=None):
    cmd = [PY, "-m", "dampertwin.sweep", "-m", "sweep=t", "tests=[monosine]", "use_calibrated=false", *args]
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=300,
                          env=dict(os.environ, MPLBACKEND="Agg", **(env or {})))


def test_sweep_root_comes_from_the_working_directory_and_all_failed_exits_nonzero(tmp_path):
    proj = _project_copy(tmp_path)
    r = _sweep(proj, "variant=baseline_1.6", "fail_on=baseline_1.6")
    failed = proj / "results" / "sweeps" / "t" / "baseline_1.6" / "_FAILED.json"
    assert failed.is_file(), r.stderr[-2000:]                      # written into the cwd's project...
    assert not (ROOT / "results" / "sweeps" / "t").exists()        # ...not into the installed source tree
    assert r.returncode != 0                                       # every variant failed


def test_sweep_explicit_root_option(tmp_path):
    proj = _project_copy(tmp_path)
    r = _sweep(tmp_path, "--root", str(proj), "variant=baseline_1.6", "fail_on=baseline_1.6")
    assert (proj / "results" / "sweeps" / "t" / "baseline_1.6" / "_FAILED.json").is_file(), r.stderr[-2000:]
    r = _sweep(tmp_path, "variant=baseline_1.6")  # outside any project, no --root
    assert r.returncode == 2 and "--root" in r.stderr


def test_sweep_project_root_resolution(tmp_path, monkeypatch):
    from dampertwin.sweep import project_root

    proj = _project_copy(tmp_path)
    monkeypatch.delenv("DAMPERTWIN_ROOT", raising=False)
    monkeypatch.chdir(proj / "conf")
    assert project_root() == proj.resolve()                         # the repository around the cwd
    monkeypatch.setenv("DAMPERTWIN_ROOT", str(ROOT))
    assert project_root() == ROOT.resolve()                         # the environment variable wins
    assert project_root(proj) == proj.resolve()                     # an explicit option wins over both
    with pytest.raises(UserError, match="no conf/ folder"):
        project_root(tmp_path)


def test_sweep_factor_without_level_is_recorded_as_failed(tmp_path):
    r = _sweep(ROOT, f"results_dir={tmp_path}", "variant=baseline_1.6", "factor=base_intake.a")
    assert r.returncode != 0 and "Traceback" not in r.stderr
    rec = json.loads((tmp_path / "t" / "baseline_1.6__base_intake.a@invalid-level" / "_FAILED.json").read_text())
    assert "level None; expected a finite number" in rec["error"]


def test_sweep_summary_table_survives_multiline_errors(tmp_path):
    from dampertwin.sweep import FAILED, summarize

    v = tmp_path / "s" / "bad"
    v.mkdir(parents=True)
    (v / FAILED).write_text(json.dumps({"error": "DesignError: 2 problems:\n  - a | b\n  - c"}))
    summarize(tmp_path / "s")
    md = (tmp_path / "s" / "summary.md").read_text().strip().splitlines()
    assert len(md) == 5 and md[-1].count("|") == md[2].count("|"), md  # title, blank, head, sep, one row


# ------------------------------------------------------------ fuzz
COLS = ["time [s]", "displacement [m]", "force [N]", "rod acceleration [m/s^2]", "current [A]", "flow [m^3/s]",
        "dp [Pa]", "force [kN]", "pressure [bar]", "comment [-]", "run", "x", "force  [N]", "lift [m]"]
CELLS = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64), st.integers(-5, 5),
                  st.text(max_size=3), st.none())


@settings(max_examples=int(os.environ.get("FUZZ_EXAMPLES", 60)), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cols=st.lists(st.sampled_from(COLS), min_size=1, max_size=5, unique=True),
       n=st.integers(0, 30), regular=st.booleans(), cells=st.lists(CELLS, min_size=1, max_size=8),
       protocol=st.sampled_from([None, "monosine", "flowbench", "topmount"]), suffix=st.sampled_from([".parquet", ".csv"]),
       rate=st.sampled_from([None, 1000.0, 50_000.0]))
def test_fuzz_measurement_frames_load_or_raise_data_error(tmp_path_factory, cols, n, regular, cells, protocol,
                                                          suffix, rate):
    data = {}
    for j, c in enumerate(cols):
        if c == "time [s]" and regular:
            data[c] = np.arange(n) / 1000.0
        else:
            data[c] = [cells[(i + j) % len(cells)] for i in range(n)]
    df = pd.DataFrame(data)
    p = tmp_path_factory.mktemp("fr") / f"m{suffix}"
    try:
        if suffix == ".csv":
            df.to_csv(p, index=False)
        else:
            write_frame(p, df, {"fuzz": True})
    except (ValueError, TypeError, OverflowError, Exception) as e:  # pyarrow cannot store mixed columns
        if not p.exists():
            p.write_bytes(repr(e).encode()[:64])  # then the loader gets an unreadable file
    try:
        read_frame(p, protocol, rate=rate)
    except DataError as e:
        assert str(p) in str(e)


def test_study_valve_map_param_is_checked_and_datasheet_keeps_the_design(tmp_path, monkeypatch):
    """params.yaml `valve_map`: an unknown value or a missing part map is one clear error naming the
    key or the file; `datasheet` is the design as written (the thesis' supplier map)."""
    from dampertwin.design import load
    from dampertwin.errors import UserError

    sys.path.insert(0, str(ROOT / "stages"))
    try:
        import _common
    finally:
        sys.path.pop(0)
    monkeypatch.setattr(_common, "params", lambda: {"profile": "ci", "valve_map": "supplier"})
    with pytest.raises(UserError, match=r"params.yaml: valve_map 'supplier'; expected one of part, datasheet"):
        _common.study_design()
    monkeypatch.setattr(_common, "params", lambda: {"profile": "ci", "valve_map": "datasheet"})
    assert _common.study_design().pq_map == load(ROOT / "conf" / "design" / "baseline.yaml").pq_map
    monkeypatch.setattr(_common, "params", lambda: {"profile": "ci"})  # the default: part
    monkeypatch.setattr(_common, "PART_MAP", tmp_path / "activevalve" / "map.csv")
    with pytest.raises(UserError, match=r"activevalve/map.csv: not found; expected the part's active-valve map"):
        _common.study_design()


def test_discrepancy_stage_reads_only_the_tests_it_declares(tmp_path, monkeypatch, capsys):
    """Stage `discrepancy` hands the workflow only the measured tests dvc.yaml declares as its deps
    (`READS`): a dyno folder in a user's measured folder is named on the terminal and left to
    `dampertwin discrepancy`, not read undeclared (DVC would not rerun the stage when it changed)."""
    sys.path.insert(0, str(ROOT / "stages"))
    try:
        import discrepancy as stage_mod
    finally:
        sys.path.pop(0)
    deps = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]["discrepancy"]["deps"]
    declared = {d.split("/", 1)[1] for d in deps if d.startswith("${measured}/")}
    assert declared - {"activevalve"} == set(stage_mod.READS)  # activevalve: the part's map (entry.part_valve_map)

    class Profile(dict):
        name, scheduler = "ci", None

    measured = tmp_path / "own"
    for t in ("flowbench", "dyno"):
        (measured / t).mkdir(parents=True)
    seen = {}
    monkeypatch.setattr(stage_mod, "config", lambda: type("C", (), {"profile": Profile(), "seed": 3})())
    monkeypatch.setattr(stage_mod, "measured_dir", lambda: measured)
    monkeypatch.setattr(stage_mod, "discrepancy", lambda *a, **k: seen.update(k) or
                        {"verdict": "none", "effects": [], "gap": {"before": 1.0, "after": 1.0}})
    monkeypatch.chdir(tmp_path)
    stage_mod.main()
    wanted = stage_mod.load_config(ROOT / "conf")["profiles"]["ci"]["tests"]
    assert "dyno" in wanted and "dyno" not in seen["tests"]
    assert seen["tests"] == {t: c for t, c in wanted.items() if t != "dyno"}
    assert "own/dyno not read by this stage" in capsys.readouterr().out


def test_sweep_summary_leaves_out_an_earlier_runs_failures(tmp_path):
    from dampertwin.sweep import FAILED, failure_attempts, summarize

    d = tmp_path / "s"
    for name in ("old_typo", "rerun_bad"):
        (d / name).mkdir(parents=True)
        (d / name / FAILED).write_text(json.dumps({"error": f"{name} failed", "attempt": 1}))
    before = failure_attempts(d)                                        # the multirun starts
    (d / "rerun_bad" / FAILED).write_text(json.dumps({"error": "failed again", "attempt": 2}))
    (d / "new_bad").mkdir()
    (d / "new_bad" / FAILED).write_text(json.dumps({"error": "new", "attempt": 1}))
    tab = summarize(d, before=before)
    assert list(tab.variant) == ["new_bad", "rerun_bad"] and (tab.status != "ok").sum() == 2   # this run's failures
    md = (d / "summary.md").read_text()
    assert "earlier run" in md and "old_typo" in md.split("|")[0] and "old_typo failed" not in md
    assert list(summarize(d).variant) == ["new_bad", "old_typo", "rerun_bad"]   # without a start: every folder
    summarize(d, before=failure_attempts(d))                            # nothing run: every record left out...
    assert "No variant results" in (d / "summary.md").read_text()        # ...and the summary says so, not the last one


def test_sweep_rerun_with_the_fix_does_not_count_the_earlier_failure(tmp_path):
    _sweep(ROOT, f"results_dir={tmp_path}", "variant=baseline_1.6", "factor=base_intake.a")   # forgot the level
    assert (tmp_path / "t" / "baseline_1.6__base_intake.a@invalid-level" / "_FAILED.json").is_file()
    r = _sweep(ROOT, f"results_dir={tmp_path}", "variant=baseline_1.6")
    assert r.returncode == 0, r.stderr[-2000:]
    md = (tmp_path / "t" / "summary.md").read_text()
    assert "failed:" not in md and "invalid-level" in md.split("|")[0], md    # named in the note, not a row
    _sweep(ROOT, f"results_dir={tmp_path}", "variant=baseline_0.9", "fail_on=baseline_0.9")   # this run's failure
    rows = [ln for ln in (tmp_path / "t" / "summary.md").read_text().splitlines() if "failed:" in ln]
    assert len(rows) == 1 and "baseline_0.9" in rows[0]                 # counted; the old typo still is not
    rec = tmp_path / "t" / "baseline_0.9" / "_FAILED.json"
    first = json.loads(rec.read_text())
    _sweep(ROOT, f"results_dir={tmp_path}", "variant=baseline_0.9", "fail_on=baseline_0.9")   # fails again
    again = json.loads(rec.read_text())
    assert (first["attempt"], again["attempt"]) == (1, 2)                # a count, not a random id or a clock
    assert {**again, "attempt": 1} == first                              # the same failure, the same record
    rows = [ln for ln in (tmp_path / "t" / "summary.md").read_text().splitlines() if "failed:" in ln]
    assert len(rows) == 1 and "baseline_0.9" in rows[0]                 # retried and failed again: counted
    _sweep(ROOT, f"results_dir={tmp_path}", "variant=baseline_0.9")     # fixed: complete, attempt 3
    assert json.loads((rec.parent / "_COMPLETE.json").read_text())["attempt"] == 3
    _sweep(ROOT, f"results_dir={tmp_path}", "variant=baseline_0.9", "seed=7", "fail_on=baseline_0.9")   # rerun, fails
    assert json.loads(rec.read_text())["attempt"] == 4                   # the count did not restart at 1...
    rows = [ln for ln in (tmp_path / "t" / "summary.md").read_text().splitlines() if "failed:" in ln]
    assert len(rows) == 1 and "baseline_0.9" in rows[0]                 # ...so this failure is counted
