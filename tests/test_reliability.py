"""Issue 13, reliability: every bad input is rejected with one error of the
project's own type naming the file (and key / column / line); here the design
inputs (ranges, YAML text, P/Q map paths, variants, fuzzed entries); the
measurements, the GA layer, stages, CLI and sweeps: tests/test_reliability_runs.py.
Each case failed on the old behaviour."""

from __future__ import annotations

import math
import os
import re
import shutil
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dampertwin.design import CONSTANTS, DesignError, load
from dampertwin.design.description import _Dumper
from dampertwin.variants import VariantError, load_variant

from conftest import BASELINE, ROOT

CONF = ROOT / "conf"
MAP = CONF / "design" / "active_valve_baseline.csv"


# ------------------------------------------------------------------ helpers
def base_doc() -> dict:
    return yaml.safe_load(BASELINE.read_text())


def entry(doc: dict, no: int) -> dict:
    return next(p for p in doc["parameters"] if p["no"] == no)


def const(doc: dict, name: str) -> dict:
    return next(c for c in doc["constants"] if c["name"] == name)


def write_design(tmp: Path, doc: dict | None = None, text: str | None = None, name="d.yaml") -> Path:
    shutil.copy(MAP, tmp / MAP.name)
    p = tmp / name
    p.write_text(text if text is not None else yaml.dump(doc, Dumper=_Dumper, sort_keys=False))
    return p


def design_rejected(path: Path, *needles: str, **kw) -> str:
    with pytest.raises(DesignError) as ei:
        load(path, **kw)
    msg = str(ei.value)
    assert str(path) in msg, msg
    for n in needles:
        assert n in msg, f"{n!r} not in {msg}"
    return msg


# ------------------------------------------------------------ physical ranges
def _set(no=None, value=None, const_name=None, bounds=None):
    def f(doc):
        e = const(doc, const_name) if const_name else entry(doc, no)
        if value is not None:
            e["value"] = value
        if bounds is not None:
            e["bounds"] = bounds
    return f


def _both(*fs):
    def f(doc):
        for g in fs:
            g(doc)
    return f


RANGE_CASES = {
    "negative rod mass": (_set(1, -0.85), "no. 1 (geometry.M_rod): value -0.85; expected > 0"),
    "zero valve mass": (_set(42, 0.0), "no. 42 (piston_rebound.m_v): value 0.0; expected > 0"),
    "zero intake valve mass": (_set(95, 0.0), "no. 95 (base_intake.m_v): value 0.0; expected > 0"),
    "K_oil 1 Pa": (_set(7, 1.0), "no. 7 (oil.K_oil): value 1.0; expected >= 1e+07"),
    "negative density": (_set(8, -850.0), "no. 8 (oil.rho_oil): value -850.0"),
    "negative temperature": (_set(15, -5.0), "no. 15 (oil.T): value -5.0; expected >= 200"),
    "temperature in degC": (_set(15, 30.0), "no. 15 (oil.T): value 30.0"),
    "negative bore": (_set(2, -0.032), "no. 2 (geometry.D_PT): value -0.032; expected > 0"),
    "rod wider than bore": (_set(3, 0.04), "no. 3 (geometry.D_R): value 0.04; expected < no. 2 (geometry.D_PT)"),
    "precharge below atmospheric": (_set(14, 90000.0), "constant 'P_atm': value 101325.0; expected < no. 14 (oil.P_0)"),
    "negative gas volume": (_set(const_name="V_gas0", value=-8e-5), "constant 'V_gas0': value -8e-05; expected > 0"),
    "vapour above saturation": (_set(11, 2e6), "no. 11 (oil.P_vap): value 2000000.0; expected < no. 10 (oil.P_sat)"),
    "discharge coefficient > 1": (_set(36, 1.5), "no. 36 (piston_rebound.Cq_max): value 1.5; expected > 0 and <= 1"),
    "tube inner radius >= outer": (_set(19, 0.03), "no. 19 (third_tube.r_i): value 0.03; expected < no. 18"),
    "shim inner >= disc diameter": (_set(35, 0.03), "no. 35 (piston_rebound.D_i): value 0.03; expected < no. 34"),
    "zero Dahl friction force": (_set(45, 0.0), "no. 45 (piston_rebound.F_c): value 0.0; expected > 0"),
    "zero stiction gap": (_set(68, 0.0), "no. 68 (piston_intake.x_v0): value 0.0; expected > 0"),
    "Coulomb above static friction": (_set(103, 90.0), "no. 103 (rod_friction.F_c): value 90.0; expected <= no. 104"),
    "zero denominator of eq. 4.34": (_both(_set(30, 0.0), _set(32, 0.0)), "(top_mount.c0) + no. 32 (top_mount.c2) > 0"),
    "Poisson ratio >= 0.5": (_set(17, 0.6), "no. 17 (third_tube.nu_p): value 0.6; expected > 0 and < 0.5"),
    "C bound 0 for a positive quantity": (_set(20, bounds=[0.0, 1000.0]),
                                          "no. 20 (top_mount.R): lower bound 0.0 1/s; expected the physical range > 0"),
    "C bound 0 for c1 (errata 33)": (_set(31, bounds=[0.0, 1e6]), "no. 31 (top_mount.c1): lower bound 0.0"),
    "zero slot area": (_set(40, 0.0), "no. 40 (piston_rebound.A_slot): value 0.0; expected > 0"),
}


@pytest.mark.parametrize("case", RANGE_CASES, ids=list(RANGE_CASES))
def test_physical_range_violations_rejected_naming_number_and_expectation(tmp_path, case):
    edit, needle = RANGE_CASES[case]
    doc = base_doc()
    edit(doc)
    design_rejected(write_design(tmp_path, doc), needle)


def test_range_violation_through_overrides_names_the_source():
    d = load(BASELINE)
    with pytest.raises(DesignError) as ei:
        d.with_overrides({"piston_rebound.m_v": -1.0}, source="conf/variant/x.yaml")
    assert "conf/variant/x.yaml" in str(ei.value) and "no. 42 (piston_rebound.m_v)" in str(ei.value)


def test_shipped_designs_satisfy_the_ranges():
    for f in (BASELINE, CONF / "lab" / "nominal.yaml"):
        load(f)


# ------------------------------------------------------------ YAML text
DUPLICATES = {
    "second value in one entry": ("  value: 0.85\n", "  value: 0.85\n  value: 0.9\n", "duplicate key 'value'"),
    "effect switch twice": ("  jet_force: true\n", "  jet_force: true\n  jet_force: false\n", "duplicate key 'jet_force'"),
    "design twice": ("design: baseline\n", "design: baseline\ndesign: other\n", "duplicate key 'design'"),
}


@pytest.mark.parametrize("case", DUPLICATES, ids=list(DUPLICATES))
def test_duplicate_yaml_keys_rejected_with_key_and_line(tmp_path, case):
    old, new, needle = DUPLICATES[case]
    text = BASELINE.read_text()
    assert old in text
    p = write_design(tmp_path, text=text.replace(old, new, 1))
    msg = design_rejected(p, needle, "line ")
    assert "first at line" in msg


def test_yaml_numbers_are_yaml_1_2():
    """1e-6 a float, `no` a string, 017 decimal (not YAML 1.1's octal 15), an unquoted 2:00:00 a string
    (not YAML 1.1's sexagesimal 7200), 0x / 0o prefixes as in YAML 1.2."""
    from dampertwin.design.yaml_io import yaml_load
    doc = yaml_load("a: 017\nb: 2:00:00\nc: 1:30\nd: 0x1F\ne: 0o17\nf: -1_000\ng: 1e-6\nno: 3\nh: +4\n")
    assert doc == {"a": 17, "b": "2:00:00", "c": "1:30", "d": 31, "e": 15, "f": -1000, "g": 1e-6, "no": 3, "h": 4}
    assert all(type(doc[k]) is int for k in "adefh")
    assert yaml_load("w: 0x_\nv: 0o_\n") == {"w": "0x_", "v": "0o_"}  # a prefix without digits: text, no crash
    # the design dumper quotes a string this loader would read as a number: it loads back a string
    import yaml as pyyaml

    from dampertwin.design.yaml_io import _Dumper
    strings = {"a": "09", "b": "0o17", "c": "1e-6", "d": "2:00:00", "e": "abc"}
    assert yaml_load(pyyaml.dump(strings, Dumper=_Dumper)) == strings


def test_a_yaml_alias_bomb_is_refused_before_anything_walks_it(tmp_path):
    """Aliases of aliases (9^9 strings from 1 kB): a config error naming the file, not a memory exhaustion
    in the first deep copy or JSON dump of it."""
    from dampertwin.design.yaml_io import ConfigTextError, yaml_load_file
    lines = ['a0: &a0 ["x","x","x","x","x","x","x","x","x"]']
    lines += [f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, 9)]
    p = tmp_path / "bomb.yaml"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(ConfigTextError, match=r"bomb.yaml: not valid YAML: the document expands to more than"):
        yaml_load_file(p)
    with pytest.raises(DesignError, match="expands to more than"):
        load(p)


def test_duplicate_key_in_variant_file_rejected(tmp_path):
    p = tmp_path / "v.yaml"
    p.write_text("case: x\nrow: 1\ntitle: t\ncurrent: 1.6\ncurrent: 0.9\noverrides: {}\n")
    with pytest.raises(VariantError, match="duplicate key 'current'"):
        load_variant(p)


@pytest.mark.parametrize("kind", ["binary", "latin-1", "oversized", "deeply nested"])
def test_unreadable_design_file_is_one_clean_error(tmp_path, kind):
    p = tmp_path / "d.yaml"
    if kind == "binary":
        p.write_bytes(b"design: x\n\x00\x01\x02\xff" * 10)
        needle = "binary file"
    elif kind == "latin-1":
        p.write_bytes("design: Dämpfer\n".encode("latin-1"))
        needle = "not UTF-8"
    elif kind == "oversized":
        p.write_text(BASELINE.read_text() + "#" + "x" * (6 * 1024 * 1024) + "\n")
        needle = "at most 5 MB"
    else:
        p.write_text("[" * 100_000 + "]" * 100_000)
        needle = "d.yaml"
    msg = design_rejected(p, needle)
    assert len(msg.splitlines()) <= 2  # one problem, no traceback text


# ------------------------------------------------------------ P/Q map paths
def test_map_outside_the_design_folder_is_refused_without_echo(tmp_path):
    secret = tmp_path / "secret"
    secret.mkdir()
    (secret / "passwd.csv").write_text("root:x:0:0:TOPSECRET:/root:/bin/bash\n")
    design_dir = tmp_path / "design"
    design_dir.mkdir()
    for value in (str(secret / "passwd.csv"), "../secret/passwd.csv", "/etc/passwd"):
        doc = base_doc()
        entry(doc, 52)["value"] = value
        msg = design_rejected(write_design(design_dir, doc), "outside the design's folder")
        assert "TOPSECRET" not in msg and "root:x" not in msg


def test_map_header_content_is_not_echoed(tmp_path):
    doc = base_doc()
    entry(doc, 52)["value"] = "bad.csv"
    (tmp_path / "bad.csv").write_text("TOPSECRET,line,here\n1,2,3\n")
    msg = design_rejected(write_design(tmp_path, doc), "first line is not the expected header")
    assert "TOPSECRET" not in msg


def test_map_with_a_byte_order_mark_loads_and_a_folder_or_flipped_flow_is_named(tmp_path):
    """A spreadsheet's UTF-8 export starts with a byte-order mark: the map loads as without it. A folder
    where the map should be, and a flow column of the wrong sign, are named as such."""
    src = (CONF / "design" / "active_valve_baseline.csv").read_text()
    doc = base_doc()
    entry(doc, 52)["value"] = "bom.csv"
    (tmp_path / "bom.csv").write_text("\ufeff" + src, encoding="utf-8")
    load(write_design(tmp_path, doc))
    entry(doc, 52)["value"] = "folder.csv"
    (tmp_path / "folder.csv").mkdir()
    design_rejected(write_design(tmp_path, doc), "folder.csv' is a folder; expected a CSV file")
    lines = src.strip().splitlines()
    flipped = [lines[0]] + [",".join(r.split(",")[:2] + [str(-float(r.split(",")[2]))]) for r in lines[1:]]
    entry(doc, 52)["value"] = "flipped.csv"
    (tmp_path / "flipped.csv").write_text("\n".join(flipped) + "\n")
    msg = design_rejected(write_design(tmp_path, doc), "the flow must be positive for dp > 0 (sign flipped?)")
    assert re.search(r"column 'flow \[m\^3/s\]' reaches -\d", msg), msg  # the flipped column's largest magnitude


def test_map_in_an_explicitly_allowed_folder_loads(tmp_path):
    out = load(BASELINE).dump(tmp_path / "elsewhere" / "d.yaml")
    design_rejected(out, "outside the design's folder")
    assert load(out, map_dirs=[CONF / "design"]).hash() == load(BASELINE).hash()


# ------------------------------------------------------------ variants
def variant(tmp: Path, **kw) -> Path:
    doc = {"case": "x", "row": 1, "title": "t", "current": 1.6, "overrides": {}}
    doc.update(kw)
    p = tmp / "x.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def test_variant_unknown_parameter_blames_the_variant_file(tmp_path):
    p = variant(tmp_path, overrides={"piston_rebound.nonsense": 1.0})
    with pytest.raises(DesignError) as ei:
        load_variant(p).apply(load(BASELINE))
    assert str(ei.value).split("\n")[1].lstrip(" -").startswith(str(p)), str(ei.value)


@pytest.mark.parametrize("row", ["eight", 0, 2.5, True])
def test_variant_bad_row_is_a_clean_error(tmp_path, row):
    with pytest.raises(VariantError, match="row"):
        load_variant(variant(tmp_path, row=row))


@pytest.mark.parametrize("current", [math.nan, math.inf, -1.0, "high"])
def test_variant_bad_current_is_a_clean_error(tmp_path, current):
    with pytest.raises(VariantError, match="current"):
        load_variant(variant(tmp_path, current=current))


@pytest.mark.parametrize("current", [7.5, 0.1])
def test_variant_current_outside_the_map_is_not_clamped(tmp_path, current):
    p = variant(tmp_path, current=current)
    with pytest.raises(VariantError) as ei:
        load_variant(p).apply(load(BASELINE))
    assert str(p) in str(ei.value) and "outside the active-valve map [0.32, 1.6] A" in str(ei.value)


@pytest.mark.parametrize("current", [math.nan, math.inf, 7.5])
def test_applying_a_case_with_a_current_the_map_lacks_is_an_error(current):
    from dampertwin.variants import Variant

    with pytest.raises(VariantError, match="conf/variant/x.yaml: current"):
        Variant("x", 1, "t", current, {}, "conf/variant/x.yaml").apply(load(BASELINE))


def test_a_map_file_name_is_searched_in_the_allowed_folders(tmp_path):
    """A calibrated design elsewhere whose case switches to another map of the
    nominal design's folder (table 6.5 row 6) finds it there; a name no
    allowed folder holds is an error naming the file."""
    from dampertwin.design import DesignError

    out = load(BASELINE).dump(tmp_path / "calibrated" / "d.yaml")
    d = load(out, map_dirs=[CONF / "design"])
    alt = d.with_overrides({"active_valve.pq_map": "active_valve_alternative.csv"})
    assert alt.pq_map != d.pq_map
    assert alt.pq_map == load(BASELINE).with_overrides({"active_valve.pq_map": "active_valve_alternative.csv"}).pq_map
    with pytest.raises(DesignError, match="nowhere.csv' not found"):
        d.with_overrides({"active_valve.pq_map": "nowhere.csv"})


# ------------------------------------------------------------ fuzz
NUMS = list(range(1, 106))
FUZZ_VALUES = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**12, 10**12),
                        st.text(max_size=6), st.none(), st.booleans(), st.lists(st.floats(), max_size=3))


@settings(max_examples=int(os.environ.get("FUZZ_EXAMPLES", 40)), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(edits=st.lists(st.tuples(st.sampled_from(NUMS), st.sampled_from(["value", "bounds", "unit", "type"]),
                                FUZZ_VALUES), min_size=1, max_size=3),
       cedits=st.lists(st.tuples(st.integers(0, len(CONSTANTS) - 1), st.sampled_from(["name", "value", "unit", "type"]),
                                 FUZZ_VALUES), max_size=2),
       effect=st.one_of(st.none(), st.tuples(st.sampled_from(["jet_force", "cavitation", "x"]), FUZZ_VALUES)),
       junk=st.one_of(st.none(), st.binary(max_size=40)))
def test_fuzz_design_entries_load_or_raise_design_error(tmp_path_factory, edits, cedits, effect, junk):
    doc = base_doc()
    for no, field, v in edits:
        entry(doc, no)[field] = v
    for i, field, v in cedits:
        doc["constants"][i][field] = v
    if effect is not None:
        doc["effects"][effect[0]] = effect[1]
    text = yaml.dump(doc, Dumper=_Dumper, sort_keys=False)
    d = tmp_path_factory.mktemp("fz")
    p = d / "fuzz.yaml"
    shutil.copy(MAP, d / MAP.name)
    data = text.encode()
    if junk is not None:  # splice random bytes into the file
        k = len(junk) * 97 % len(data)
        data = data[:k] + junk + data[k:]
    p.write_bytes(data)
    try:
        load(p)
    except DesignError as e:
        assert str(p) in str(e)
