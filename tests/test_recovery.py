"""The recovery stage (issue 32, acceptance 5): the fitted model against the
lab's truth where both have the quantity. Hand-computed values of each
side, planted errors, and the stage end to end on a fake results tree (the
overlays in the layout the fit stages write), traced for its DVC wiring.
SYNTHETIC: the truth is the virtual lab's reference damper."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import ROOT

sys.path.insert(0, str(ROOT / "stages"))

import _recovery as rc  # noqa: E402
from dampertwin import lab  # noqa: E402
from dampertwin.design import load  # noqa: E402
from dampertwin.truth.params import index  # noqa: E402
from dampertwin.truth.part import build  # noqa: E402

CONF = ROOT / "conf"
SAMPLE = lab.load_sample(CONF / "lab" / "sample.yaml")
TRUTH_K0 = SAMPLE["truth"]["values"]["oil.K0"]  # 9e8 Pa
TRUTH_ALPHA = SAMPLE["truth"]["values"]["alpha_free"]  # 0.0055


@pytest.fixture(scope="module")
def base():
    return load(CONF / "design" / "baseline.yaml")


@pytest.fixture(scope="module")
def nominal_part():
    """The truth of the nominal part, exactly its drawings (no sample, not as built)."""
    nom = lab.load_design(CONF / "lab" / "nominal.yaml")
    p, rest, _ = build(nom, nom)
    return p, rest, nom


def test_model_free_gas_by_hand(base):
    """Eq. 4.14-4.15 at rest: theta(P0) chi T/T_ref (P_ref/P0)^(1/Gamma) /
    ((1 - chi) exp(-(P0 - P_ref)/K_oil)), numbers of conf/design/baseline.yaml."""
    P0, P_ref, chi = 401325.0, 101325.0, 0.0035
    theta = 1 - (P0 - 2000.0) / (1e6 - 2000.0)  # P_vap 20 mbar, P_sat 10 bar
    gas = theta * chi * 303.15 / 293.15 * (P_ref / P0) ** (1 / 1.4)
    want = gas / ((1 - chi) * math.exp(-(P0 - P_ref) / 7.7e8))
    assert rc.model_free_gas(base) == pytest.approx(want, rel=1e-12)
    assert rc.model_free_gas(base.with_overrides({"effects.gas_content": False})) == 0.0


def test_truth_free_gas_and_modulus_by_hand():
    """The sample's entrained gas at rest: alpha_free [m^3 at P_ref per m^3
    liquid] at the precharge as isothermal bubbles; oil modulus Murnaghan
    K0 + K1 (P - P_ref) with K1 = 11."""
    p, rest = lab.truth_part(lab.load_design(CONF / "lab" / "nominal.yaml"),
                             lab.load_design(CONF / "lab" / "nominal.yaml"), SAMPLE)
    assert rest["P0"] == 401325.0
    assert rc.truth_free_gas(p, rest["P0"]) == pytest.approx(TRUTH_ALPHA * 101325.0 / 401325.0, rel=1e-12)
    assert rc.truth_oil_modulus(p, 101325.0) == pytest.approx(TRUTH_K0, rel=1e-15)
    assert rc.truth_oil_modulus(p, 401325.0) == pytest.approx(TRUTH_K0 + 11.0 * 3e5, rel=1e-15)


def test_truth_lift_force_by_hand(nominal_part):
    """Shim stack: F(0) = the drawing's preload; below the crossover the face
    set's rate K1; beyond it K1 (x + DELTA) + K2 PSI (PSI x - GAP). Intake:
    F_S + K_S x = 10 N + 6e5 N/m x (design preload, truth's coil spring)."""
    p, _, nom = nominal_part
    v = "piston_rebound"
    K1, K2, PSI, GAP, DELTA = (p[index(f"{v}.{k}")] for k in ("K1", "K2", "PSI", "GAP", "DELTA"))
    x_in, x_out = 0.5 * GAP / PSI, 2.0 * GAP / PSI
    F = rc.truth_lift_force(p, v, np.array([0.0, x_in, x_out]))
    assert F[0] == pytest.approx(nom["piston_rebound.F_preload"], rel=1e-9)
    assert F[1] == pytest.approx(K1 * (x_in + DELTA), rel=1e-9)
    assert F[2] == pytest.approx(K1 * (x_out + DELTA) + K2 * PSI * (PSI * x_out - GAP), rel=1e-6)
    F = rc.truth_lift_force(p, "piston_intake", np.array([0.0, 1e-4]))
    np.testing.assert_allclose(F, [10.0, 70.0], rtol=1e-12)
    with pytest.raises(ValueError, match="active_valve"):
        rc.truth_lift_force(p, "active_valve", np.array([0.0]))


def test_model_lift_force_is_eq_4_19(base):
    x = np.linspace(0.0, 2e-4, 5)
    want = 200 + 300 * (np.exp(4000 * x) - 1) - 200 * (np.exp(-15000 * x) - 1)
    np.testing.assert_allclose(rc.model_lift_force(base, "piston_rebound", x), want, rtol=1e-12)


def test_curve_error_and_relative_error():
    t = np.array([100.0, 200.0, 400.0])
    assert rc.curve_error(t, t) == 0.0
    assert rc.curve_error(t * [1.0, 1.1, 0.95], t) == pytest.approx(0.10)
    assert rc.rel_error(9.9e8, 9e8) == pytest.approx(0.10)
    assert rc.rel_error(8.1e8, 9e8) == pytest.approx(-0.10)


def test_truth_top_mount_is_a_passive_stiffening_rubber():
    """A generalised Maxwell rubber: loss angle in (0, 90) deg and |K*| rising
    with frequency (a sign or harmonic error breaks both)."""
    nom = lab.load_design(CONF / "lab" / "nominal.yaml")
    p, rest = lab.truth_part(nom, nom, SAMPLE)
    rows = rc.truth_dynamic_stiffness(p, rest, [2.0, 20.0, 120.0], 1e-4)
    K = [r["stiffness [N/m]"] for r in rows]
    assert all(0.0 < r["loss angle [deg]"] < 90.0 for r in rows), rows
    assert K[0] < K[1] < K[2], K
    assert 5e5 < K[0] < 5e6  # the backbone's order (K_E = 1.2e6 N/m)


# ---------------------------------------------------------------- end to end
def _chi_for_free_gas(base, target: float) -> float:
    """The oil.chi whose model free gas at rest is ``target`` (inverting eq. 4.15 by hand)."""
    P0, P_ref = base["oil.P_0"], base["constants.P_ref"]
    theta = 1 - (P0 - base["oil.P_vap"]) / (base["oil.P_sat"] - base["oil.P_vap"])
    per = theta * base["oil.T"] / base["constants.T_ref"] * (P_ref / P0) ** (1 / base["oil.Gamma"])
    r = target * math.exp(-(P0 - P_ref) / TRUTH_K0) / per  # chi / (1 - chi) with K_oil = the truth's K0
    return r / (1 + r)


def fake_results(root: Path, base) -> Path:
    """results/ with every overlay the stage reads: nominal valves and top
    mounts (empty overrides), approach 1's compliance = the truth (free gas
    and K0), approach 2's K_oil 10 % above the truth's."""
    import recovery

    res = root / "results"
    truth_gas = TRUTH_ALPHA * base["constants.P_ref"] / base["oil.P_0"]
    planted = {"compliance": {"oil.chi": _chi_for_free_gas(base, truth_gas), "oil.K_oil": TRUTH_K0},
               "approach2": {"oil.K_oil": 1.1 * TRUTH_K0}}
    for key, path in recovery.inputs(CONF, res).items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(yaml.safe_dump({"fit": "fake (tests/test_recovery.py)", "overrides": planted.get(key, {})}))
    return res


def test_stage_end_to_end_on_a_fake_results_tree(tmp_path, base):
    import recovery

    res = fake_results(tmp_path, base)
    m = recovery.run(CONF, res, tmp_path / "out")
    assert m["free_gas_error_pct"]["approach 1"] == pytest.approx(0.0, abs=1e-9)
    assert m["oil_modulus_P_ref_error_pct"]["approach 1"] == pytest.approx(0.0, abs=1e-12)
    assert m["oil_modulus_P_ref_error_pct"]["approach 2"] == pytest.approx(10.0, rel=1e-12)
    assert m["oil_modulus_P_ref_error_pct"]["nominal"] == pytest.approx(100 * (7.7e8 - 9e8) / 9e8)
    v = m["valve_curve_max_error_pct"]
    assert set(v["approach 1"]) == set(v["nominal"]) and len(v["nominal"]) == 8
    assert set(v["approach 2"]) == {"piston_rebound", "piston_intake", "base_compression", "base_intake"}
    assert v["approach 1"] == v["nominal"]  # empty valve overlays: the nominal curves
    assert all(x > 0 for x in v["nominal"].values())
    assert m["topmount_fitted_stiffness_max_abs_error_pct"] == m["topmount_nominal_stiffness_max_abs_error_pct"]
    on_disk = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert on_disk["code_hash"].startswith("sha256:") and on_disk["synthetic"] is True
    assert {k: v for k, v in on_disk.items() if k != "code_hash"} == json.loads(json.dumps(m))
    doc = json.loads((tmp_path / "out" / "recovery.json").read_text())
    c = next(c for c in doc["valves"] if c["valve design"] == "piston_intake")
    x = np.asarray(c["lift [m]"])
    assert 0 < x[-1] < base["constants.x_max_piston_intake"]
    np.testing.assert_allclose(c["truth [N]"][-1], c["truth [N]"][0] + (c["truth [N]"][1] - c["truth [N]"][0])
                               / x[1] * x[-1], rtol=1e-9)  # the coil spring is linear
    md = (tmp_path / "out" / "recovery.md").read_text()
    assert "SYNTHETIC" in md and "not fitted" in md
    for f in ("valves.png", "topmount.png", "metrics.json"):
        assert (tmp_path / "out" / f).stat().st_size > 0
    first = {f: (tmp_path / "out" / f).read_bytes() for f in ("recovery.md", "recovery.json", "valves.png")}
    recovery.run(CONF, res, tmp_path / "out")
    assert all((tmp_path / "out" / f).read_bytes() == b for f, b in first.items())  # same input, same bytes


def test_stage_reads_exactly_its_dvc_deps_and_writes_its_outs(tmp_path, base):
    """The script as DVC runs it (python stages/recovery.py) in a copy of the
    repository, every file open traced (tests/tracer): the files it reads
    under the copy are its declared deps, each declared file dep is read,
    and it writes exactly its declared outs."""
    repo = tmp_path / "repo"
    for d in ("conf", "stages"):
        shutil.copytree(ROOT / d, repo / d, ignore=shutil.ignore_patterns("__pycache__"))
    for f in ("dvc.yaml", "pyproject.toml", "params.yaml"):
        shutil.copy(ROOT / f, repo / f)
    fake_results(repo, base)
    trace = tmp_path / "trace"
    trace.mkdir()
    env = dict(os.environ, DAMPERTWIN_TRACE=str(trace),
               PYTHONPATH=os.pathsep.join([str(ROOT / "tests" / "tracer"), str(ROOT / "src")]))
    r = subprocess.run([sys.executable, "stages/recovery.py"], cwd=repo, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    reads, writes = set(), set()
    for log in trace.glob("*.log"):
        for line in log.read_text().splitlines():
            _, mode, path = line.split("\t")
            p = Path(path)
            if not p.is_relative_to(repo) or "__pycache__" in p.parts:
                continue
            if mode == "w":
                writes.add(p.relative_to(repo).as_posix())
            elif p.is_file():
                reads.add(p.relative_to(repo).as_posix())
    st = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]["recovery"]
    deps = st["deps"]
    outs = [next(iter(o)) for o in st["outs"] + st["metrics"]]
    stray = [f for f in reads if not any(f == d or f.startswith(d + "/") for d in deps)]
    assert not stray, stray
    unread = [d for d in deps if (repo / d).is_file() and d not in reads]
    assert not unread, unread
    final = {re.sub(r"/\.([^/]+)\.tmp\d+$", r"/\1", w) for w in writes}  # atomic writes: .NAME.tmpPID -> NAME
    assert final == set(outs)


def test_another_sample_is_compared_with_its_own_truth(tmp_path, base):
    """--sample: the recovery of a study run on another lab sample (conf/lab/sample2.yaml,
    oil.K0 6.5e8) is measured against that sample's truth, not the stage's sample (9e8)."""
    import recovery

    res = fake_results(tmp_path, base)
    m = recovery.run(CONF, res, tmp_path / "out2", CONF / "lab" / "sample2.yaml")
    assert m["oil_modulus_P_ref_error_pct"]["nominal"] == pytest.approx(100 * (7.7e8 - 6.5e8) / 6.5e8)
    with pytest.raises(recovery.UserError, match="sample_missing.yaml: file not found"):
        recovery.main("--sample", str(tmp_path / "sample_missing.yaml"), "--out", str(tmp_path / "o"))
