"""Lab-3 samples (issue 32, acceptance 7): conf/lab/sample.yaml and
sample2.yaml carry the truth's parameters, the lab measures them on the
reference damper (dampertwin.truth), every record says synthetic and names
the truth's version, and the schema refuses unknown keys and effects naming
the file and the key."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from conftest import ROOT
from dampertwin import cli
from dampertwin import lab as labmod
from dampertwin.design import load
from dampertwin.io import read_meta
from dampertwin.lab import check_sample, load_sample, run_lab, truth_part
from dampertwin.truth import TRUTH_VERSION
from dampertwin.truth import params as tp
from dampertwin.truth.part import build

CONF = ROOT / "conf"
SAMPLES = (CONF / "lab" / "sample.yaml", CONF / "lab" / "sample2.yaml")
NOMINAL = CONF / "lab" / "nominal.yaml"


@pytest.mark.parametrize("path", SAMPLES, ids=lambda p: p.name)
def test_shipped_samples_are_lab3_truth_samples(path):
    s = load_sample(path)
    assert s["generator"] == labmod.LAB3_VERSION and labmod.is_truth_sample(s)
    check_sample(s, load(NOMINAL))


def test_records_are_synthetic_name_the_truth_and_are_reproducible(tmp_path):
    only = [("flowbench", "piston_intake")]
    a = run_lab(SAMPLES[0], tmp_path / "a", seed=3, only=only, progress=False, conf=CONF, workers=1)
    b = run_lab(SAMPLES[0], tmp_path / "b", seed=3, only=only, progress=False, conf=CONF, workers=1)
    assert a[0].read_bytes() == b[0].read_bytes()
    meta = read_meta(a[0])
    assert meta["synthetic"] is True and meta["generator"] == labmod.LAB3_VERSION
    assert meta["truth"] == TRUTH_VERSION and TRUTH_VERSION in meta["note"] and "SYNTHETIC" in meta["note"]
    assert meta["sample_hash"] == load_sample(SAMPLES[0])["_hash"]


def test_each_sample_is_its_own_part_as_built():
    """The two samples and the nominal drawings give three different parts;
    no area, volume or spring rate is off its drawing by more than 2 %."""
    nominal = load(NOMINAL)
    parts = [truth_part(nominal, nominal, load_sample(p))[0] for p in SAMPLES]
    exact, _, _ = build(nominal, nominal, load_sample(SAMPLES[0])["truth"], as_built_seed=None)
    assert not np.array_equal(parts[0], parts[1]) and not np.array_equal(parts[0], exact)
    for b, n in tp.DEVIATING:
        i = tp.index(f"{b}.{n}")
        assert abs(parts[0][i] / exact[i] - 1) <= tp.AS_BUILT + 1e-12
    moved = [abs(parts[0][tp.index(f"{b}.{n}")] / exact[tp.index(f"{b}.{n}")] - 1) for b, n in tp.DEVIATING]
    assert max(moved) > 0.01  # really drawn, not all at the drawing


def _bad(tmp_path, edit):
    doc = yaml.safe_load(SAMPLES[0].read_text())
    edit(doc)
    p = tmp_path / "bad_truth_sample.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


@pytest.mark.parametrize("edit, key", [
    (lambda d: d.update(colour="red"), "colour"),
    (lambda d: d.update(factors={}), "factors"),
    (lambda d: d["truth"]["effects"].update(warp_drive=True), "truth.effects.warp_drive"),
    (lambda d: d["truth"]["values"].update({"piston_rebound.zz": 1.0}), "truth.values.piston_rebound.zz"),
    (lambda d: d["truth"]["values"].update({"seal.F0": "tight"}), "truth.values.seal.F0"),
    (lambda d: d["truth"].update(colour=1), "truth.colour"),
    (lambda d: d["benches"].update(wind={"speed": 3.0}), "benches.wind"),
    (lambda d: d.pop("truth"), "truth"),
])
def test_bad_truth_sample_exits_2_naming_file_and_key(tmp_path, capsys, edit, key):
    p = _bad(tmp_path, edit)
    rc = cli.main(["lab", "--sample", str(p), "--out", str(tmp_path / "out"), "--tests", "monosine"])
    err = capsys.readouterr().err
    assert rc == 2 and str(p) in err and key in err, err
    assert not (tmp_path / "out").exists()


def test_design_variants_reach_the_truths_own_parts():
    """A design variant changes the truth's parts as the design says: the
    softer piston-rebound stack has its initial stiffness scaled as the
    design's (shim thickness ~ stiffness^(1/3)), the stiffer top mount its
    rubber, another valve datasheet the solenoid; the baseline is untouched."""
    from dampertwin.variants import load_variant

    nominal = load(NOMINAL)
    base, _, _ = build(nominal, nominal)
    soft = load_variant(CONF / "variant" / "lower_piston_rebound.yaml").apply(nominal)
    p, _, _ = build(soft, nominal)
    g0, g1 = nominal.group("piston_rebound"), soft.group("piston_rebound")
    ratio = (g1["a"] * g1["b"] + g1["c"] * g1["d"]) / (g0["a"] * g0["b"] + g0["c"] * g0["d"])
    i = tp.index("piston_rebound.K1")
    assert p[i] / base[i] == pytest.approx(ratio, rel=1e-9) and ratio < 1
    mount = load_variant(CONF / "variant" / "alternative_top_mount.yaml").apply(nominal)
    p, _, _ = build(mount, nominal)
    assert p[tp.index("mount.K_E")] / base[tp.index("mount.K_E")] == pytest.approx(1.6)
    valve = load_variant(CONF / "variant" / "different_active_valve.yaml").apply(nominal)
    p, _, _ = build(valve, nominal)
    assert p[tp.index("active_valve.F_S")] > base[tp.index("active_valve.F_S")]
    same = np.flatnonzero(p != base)
    assert {tp.PARAM_NAMES[k].split(".")[0] for k in same} == {"active_valve"}
