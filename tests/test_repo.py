"""Repository contracts: README quick start == CI, CLI behaviour, dvc.yaml."""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from dampertwin.cli import main

ROOT = Path(__file__).resolve().parents[1]


def quick_start_commands():
    text = (ROOT / "README.md").read_text()
    section = text.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    return [c.strip() for c in re.findall(r"```bash\n#[^\n]*\n(.+?)\n```", section, re.S)]


def test_readme_has_exactly_two_quick_start_commands_and_ci_runs_the_second():
    cmds = quick_start_commands()
    assert len(cmds) == 2, cmds
    assert cmds[1] in (ROOT / ".ci" / "run").read_text()


def test_cli_show_and_check(capsys, tmp_path):
    base = ROOT / "conf/design/baseline.yaml"
    assert main(["design", "show", str(base), "--type", "C"]) == 0
    out = capsys.readouterr().out
    assert "piston_rebound.a" in out and "oil.K_oil" not in out
    assert main(["design", "check", str(base)]) == 0
    bad = tmp_path / "bad.yaml"
    bad.write_text(base.read_text().replace("unit: kg\n", "unit: g\n", 1))
    assert main(["design", "check", str(bad)]) == 1
    err = capsys.readouterr().err
    assert "no. 1 (geometry.M_rod)" in err and str(bad) in err


def test_cli_entry_point_exit_code(tmp_path):
    r = subprocess.run([sys.executable, "-m", "dampertwin.cli", "design", "check", str(tmp_path / "nope.yaml")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "file not found" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_dvc_yaml_is_valid():
    doc = yaml.safe_load((ROOT / "dvc.yaml").read_text())
    assert isinstance(doc.get("stages"), dict)


def _tracked_files():
    r = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    if r.returncode != 0:  # not a git checkout (e.g. an sdist): every file under the root
        return [p.relative_to(ROOT).as_posix() for p in ROOT.rglob("*")
                if p.is_file() and ".venv" not in p.parts and ".git" not in p.parts]
    return r.stdout.split()


def test_no_reference_outside_the_repository():
    """Docs the code cites live in docs/; nothing points to a sibling folder."""
    needle = ".." + "/shared"  # split so this file does not match itself
    bad = []
    for rel in _tracked_files():
        p = ROOT / rel
        if p.suffix in (".parquet", ".png", ".npz") or not p.is_file():
            continue
        try:
            text = p.read_text()
        except UnicodeDecodeError:
            continue
        if needle in text:
            bad.append(rel)
    assert not bad, f"files referencing {needle}: {bad}"
    for doc in ("docs/THESIS-ERRATA.md", "docs/DESIGN.md"):
        assert (ROOT / doc).is_file(), doc


def test_errata_cited_by_the_design_exist_in_docs():
    errata = (ROOT / "docs" / "THESIS-ERRATA.md").read_text()
    numbers = {int(n) for n in re.findall(r"^(\d+)\. \*\*", errata, re.M)}
    assert numbers == set(range(1, max(numbers) + 1))
    cited = set()
    for rel in ("conf/design/baseline.yaml", "conf/lab/nominal.yaml"):
        cited |= {int(n) for n in re.findall(r"(?:ERRATA|errata)\.?(?:md)?(?: item)? (\d+)", (ROOT / rel).read_text())}
    assert cited and cited <= numbers, cited - numbers


def test_measured_folder_is_a_param_and_only_the_lab_writes_data_measured():
    params = yaml.safe_load((ROOT / "params.yaml").read_text())
    assert params["measured"] == "data/measured"
    doc = yaml.safe_load((ROOT / "dvc.yaml").read_text())
    for name, st in doc["stages"].items():
        body = st.get("do", st)
        deps = [str(d) for d in body.get("deps", [])]
        outs = [next(iter(o)) if isinstance(o, dict) else o for o in body.get("outs", [])]
        if name == "lab":
            assert outs == ["data/measured"]
            continue
        assert not any("data/measured" in d for d in deps), (name, deps)  # read through ${measured}
        assert not any(o.startswith("data/") for o in outs), (name, outs)  # data/own is never written
        if any("${measured}" in d for d in deps):
            assert "measured" in body.get("params", []), name


def test_dvc_plots_one_per_kpi_family_with_identity_line_and_case_tooltip():
    import json

    doc = yaml.safe_load((ROOT / "dvc.yaml").read_text())
    plots = [next(iter(p)) for p in doc["stages"]["compare"]["plots"]]
    assert plots == ["results/approach1/plots/kpi_peaks.csv", "results/approach1/plots/kpi_psd.csv"]
    tpl = json.loads((ROOT / ".dvc" / "plots" / "kpi_scatter.json").read_text())
    line, points = tpl["layer"]
    assert line["encoding"]["x"]["field"] == line["encoding"]["y"]["field"]  # y = x
    assert {"field": "case", "type": "nominal"} in points["encoding"]["tooltip"]
    cfg = (ROOT / ".dvc" / "config").read_text()
    assert "remote = " in cfg  # a default remote: dvc push works


def _pipeline_stage_names() -> set[str]:
    """Stage names of dvc.yaml as dvc.lock spells them (foreach items as NAME@KEY)."""
    doc = yaml.safe_load((ROOT / "dvc.yaml").read_text())
    names = set()
    for name, st in doc["stages"].items():
        each = st.get("foreach")
        if each is None:
            names.add(name)
        elif isinstance(each, dict):
            names |= {f"{name}@{k}" for k in each}
        elif isinstance(each, list):
            names |= {f"{name}@{k}" for k in each}
        else:  # an interpolated foreach: not resolvable here, accept any NAME@...
            names.add(f"{name}@*")
    return names


def test_dvc_lock_has_no_stage_the_pipeline_lacks():
    lock = yaml.safe_load((ROOT / "dvc.lock").read_text())
    names = _pipeline_stage_names()
    stale = [s for s in lock.get("stages", {}) if s not in names and f"{s.split('@')[0]}@*" not in names]
    assert not stale, f"dvc.lock has stages dvc.yaml lacks: {stale}"


def test_metrics_writer_records_the_code_hash(tmp_path):
    sys.path.insert(0, str(ROOT / "stages"))
    try:
        from _common import write_json
    finally:
        sys.path.remove(str(ROOT / "stages"))
    from dampertwin.provenance import code_hash

    write_json(tmp_path / "metrics.json", {"a": 1.0})
    write_json(tmp_path / "other.json", {"a": 1.0})
    import json

    doc = json.loads((tmp_path / "metrics.json").read_text())
    assert doc == {"a": 1.0, "code_hash": code_hash()}
    assert re.fullmatch(r"sha256:[0-9a-f]{16}", doc["code_hash"])
    assert "code_hash" not in json.loads((tmp_path / "other.json").read_text())


def test_stage_json_is_standard_json(tmp_path):
    """An unbounded interval or undefined ratio is written as null, never Infinity / NaN (RFC 8259), and read
    back as the unbounded interval it was."""
    import json

    import numpy as np

    sys.path.insert(0, str(ROOT / "stages"))
    try:
        from _common import write_json
    finally:
        sys.path.remove(str(ROOT / "stages"))
    from dampertwin.calibration.uncertainty import summary

    write_json(tmp_path / "u.json", {"parameters": [{"parameter": "a", "value": np.float64(2.0),
                                                     "ci95 low": -np.inf, "ci95 high": np.inf,
                                                     "rel. half-width [%]": np.inf, "determined": np.bool_(False),
                                                     "why": "x"}], "n_samples": np.int64(3), "n_eff": np.nan,
                                     "undetermined": ["a"], "correlation": [[1.0]]})
    text = (tmp_path / "u.json").read_text()
    doc = json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in stage JSON"))
    assert doc["n_eff"] is None and doc["parameters"][0]["ci95 high"] is None and doc["n_samples"] == 3
    p = summary(doc)["parameters"]["a"]
    assert p["ci95"] == [-np.inf, np.inf] and p["rel_halfwidth"] == np.inf and p["value"] == 2.0
    from dampertwin.study_report import fit_rows
    write_json(tmp_path / "fits.json", {"fits": {"f": {"values": {"a": 2.0}, "uncertainty": summary(doc)}}})
    row = fit_rows(json.loads((tmp_path / "fits.json").read_text()))[0].iloc[0]  # the report reads it back
    assert row["95 % interval"] == [-np.inf, np.inf] and row["rel. half-width [%]"] == np.inf
    from dampertwin.study_report import determined_tables
    det = {"quantity": "q", "rows": [{"frequency [Hz]": 10.0, "stiffness [N/m]": 2e5, "loss angle [deg]": 3.0,
                                      "stiffness ci95 [N/m]": [-np.inf, np.inf], "loss angle ci95 [deg]": [1.0, np.inf]}]}
    write_json(tmp_path / "fits.json", {"fits": {"f": {"values": {}, "objective_start": np.nan, "objective_best": 2.0,
                                                       "determined": det}}})
    fits = json.loads((tmp_path / "fits.json").read_text())
    assert not fit_rows(fits)[1]  # an undefined start flags nothing (nan compares false), as before null
    assert "| 10 | 200 | [-inf, inf] | 3 | [1, inf] |" in "\n".join(determined_tables(fits))
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        from mkdocs_hooks import _metrics_table
    finally:
        sys.path.remove(str(ROOT / "scripts"))
    assert _metrics_table({"m": {"mean_abs": None, "max_abs": 1.0}})[-1] == "| m | - | 1 |"


def test_record_metadata_is_standard_json(tmp_path):
    """A record's Parquet metadata is standard JSON too: a non-finite value is null, numpy values are numbers."""
    import json

    import numpy as np
    import pandas as pd
    import pyarrow.parquet as pq

    from dampertwin.io import META_KEY, read_meta, write_frame

    p = write_frame(tmp_path / "r.parquet", pd.DataFrame({"time [s]": [0.0, 1.0]}),
                    {"noise": np.nan, "band": [-np.inf, np.float64(2.5)], "n": np.int64(3), "ok": np.bool_(True),
                     "scalar": np.array(0.5)})
    raw = pq.read_schema(p).metadata[META_KEY].decode()
    json.loads(raw, parse_constant=lambda c: pytest.fail(f"{c} in record metadata"))
    assert read_meta(p) == {"noise": None, "band": [None, 2.5], "n": 3, "ok": True, "scalar": 0.5}


def test_committed_json_is_standard_json():
    """Every committed JSON file parses without Infinity / NaN tokens (jq, browsers and JSON schema refuse them)."""
    import json

    bad = []
    for rel in _tracked_files():
        if rel.endswith(".json"):
            try:
                json.loads((ROOT / rel).read_text(), parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
            except ValueError as e:
                bad.append(f"{rel}: {e}")
    assert not bad, bad


def test_code_hash_follows_the_source(tmp_path):
    import shutil

    from dampertwin.provenance import PACKAGE, code_hash

    pkg = tmp_path / "dampertwin"
    shutil.copytree(PACKAGE, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    assert code_hash(pkg) == code_hash(PACKAGE)
    (pkg / "__pycache__").mkdir(exist_ok=True)
    (pkg / "__pycache__" / "x.py").write_text("ignored")
    assert code_hash(pkg) == code_hash(PACKAGE)
    (pkg / "kpi.py").write_text((pkg / "kpi.py").read_text() + "\n# edited\n")
    assert code_hash(pkg) != code_hash(PACKAGE)


def _committed_metrics():
    return [ROOT / rel for rel in _tracked_files() if rel.startswith("results/") and rel.endswith("metrics.json")]


def test_committed_metrics_carry_the_code_hash():
    import json

    files = _committed_metrics()
    assert files
    missing = [str(p.relative_to(ROOT)) for p in files if "code_hash" not in json.loads(p.read_text())]
    assert not missing, f"metrics without code_hash: {missing}"


def test_committed_results_came_from_this_code():
    """Every committed metrics.json names the hash of the source it was made
    with, and it is this checkout's: a commit that changes src/dampertwin
    without rerunning the study fails here (rerun `dvc repro`, commit the
    results and dvc.lock together)."""
    import json

    from dampertwin.provenance import code_hash

    got = {str(p.relative_to(ROOT)): json.loads(p.read_text()).get("code_hash") for p in _committed_metrics()}
    stale = {k: v for k, v in got.items() if v != code_hash()}
    assert not stale, f"results made with other code than {code_hash()}: {stale}"


def test_committed_fits_name_the_active_valve_map_of_params():
    """The compliance fit runs through the active valve: fits.json records which map (params.yaml valve_map)."""
    import json

    import yaml

    fits = json.loads((ROOT / "results" / "approach1" / "fits.json").read_text())["fits"]
    want = yaml.safe_load((ROOT / "params.yaml").read_text()).get("valve_map", "part")
    assert fits["compliance"].get("valve_map") == want
    assert all("valve_map" not in f for n, f in fits.items() if n.startswith("valves/"))  # the flow bench has none


def test_dvc_lock_matches_the_code_and_configs():
    """`dvc status`: no stage's code, config or parameter dependency differs
    from dvc.lock (data outputs absent from a fresh clone are not counted)."""
    import json

    dvc = shutil.which("dvc")
    if dvc is None:
        pytest.skip("dvc not installed")
    res = subprocess.run([dvc, "status", "--json"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    changed = {}
    for stage, entries in json.loads(res.stdout or "{}").items():
        for entry in entries:
            if not isinstance(entry, dict):
                continue
            deps = {k: v for k, v in entry.get("changed deps", {}).items() if v == "modified"}
            if deps or entry.get("changed params"):
                changed[stage] = (deps, entry.get("changed params"))
    assert not changed, f"dvc.lock is stale for: {changed}"


def test_committed_outputs_open_offline():
    """report.html and the plots page embed their images; no committed CSV is header-only."""
    import pandas as pd

    for rel in ("results/approach1/report.html", "results/approach1/plots/index.html"):
        page = (ROOT / rel).read_text()
        srcs = re.findall(r'<img src="([^"]+)"', page)
        assert all(s.startswith("data:image/png;base64,") for s in srcs), rel
        assert "<script" not in page and "http://" not in page and "https://" not in page, rel
    assert re.findall(r'<img src="data:', (ROOT / "results/approach1/plots/index.html").read_text())
    for rel in _tracked_files():
        if rel.endswith(".csv"):
            assert len(pd.read_csv(ROOT / rel)) > 0, f"{rel}: no rows"


def _stage_scripts():
    """(stage name, script path, declared params) of every dvc.yaml stage (foreach bodies once)."""
    doc = yaml.safe_load((ROOT / "dvc.yaml").read_text())
    for name, st in doc["stages"].items():
        body = st.get("do", st)
        script = next((w for w in body["cmd"].split() if w.endswith(".py")), None)
        if script:
            yield name, ROOT / script, body.get("params", [])


def test_config_hash_covers_only_params_every_writer_declares(monkeypatch):
    """The config hash in a stage's outputs depends on no params.yaml key that stage leaves undeclared:
    every stage that writes it declares HASHED_PARAMS and all of conf/config.yaml, and a key outside
    HASHED_PARAMS (valve_map) leaves the hash unchanged while a hashed one (profile) changes it."""
    sys.path.insert(0, str(ROOT / "stages"))
    try:
        import _common
    finally:
        sys.path.remove(str(ROOT / "stages"))
    writers = 0
    for name, script, declared in _stage_scripts():
        text = script.read_text()
        if "config_hash" not in text and "write_fit" not in text:
            continue
        writers += 1
        flat = {p for p in declared if isinstance(p, str)}
        whole = [p for p in declared if isinstance(p, dict) and "conf/config.yaml" in p]
        assert set(_common.HASHED_PARAMS) <= flat, (name, declared)
        assert whole and whole[0]["conf/config.yaml"] is None, (name, "conf/config.yaml: all keys", declared)
    assert writers >= 10
    base = _common.params()
    h = _common.config_hash()
    monkeypatch.setattr(_common, "params", lambda: {**base, "valve_map": "datasheet" if base.get("valve_map") != "datasheet" else "part"})
    assert _common.config_hash() == h
    monkeypatch.setattr(_common, "params", lambda: {**base, "profile": "ci" if base["profile"] != "ci" else "full"})
    assert _common.config_hash() != h
