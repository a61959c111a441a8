"""Design description: completeness of the baseline, strict validation,
round trip, overrides."""

from __future__ import annotations

import copy
import functools
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dampertwin.design import EFFECTS, Design, DesignError, load, loads
from dampertwin.design.description import _Dumper
from dampertwin.design.schema import BY_NUMBER, MAP_COLUMNS

ROOT = Path(__file__).resolve().parents[1]
BASELINE = ROOT / "conf" / "design" / "baseline.yaml"
CONF = BASELINE.parent


@pytest.fixture(scope="module")
def base() -> Design:
    return load(BASELINE)


@pytest.fixture()
def doc() -> dict:
    return yaml.safe_load(BASELINE.read_text())


def write(tmp_path: Path, doc: dict, name="design.yaml", map_src=CONF / "active_valve_baseline.csv") -> Path:
    """Write a (corrupted) document beside a copy of the P/Q map."""
    if map_src is not None:
        (tmp_path / "active_valve_baseline.csv").write_text(map_src.read_text())
    p = tmp_path / name
    p.write_text(yaml.dump(doc, Dumper=_Dumper, sort_keys=False))
    return p


def entry(doc: dict, no: int) -> dict:
    return next(p for p in doc["parameters"] if p["no"] == no)


def rejected(path: Path, *needles: str) -> str:
    with pytest.raises(DesignError) as ei:
        load(path)
    msg = str(ei.value)
    assert str(path) in msg, msg
    for n in needles:
        assert n in msg, f"{n!r} not in {msg}"
    return msg


# ------------------------------------------------------------ the baseline
def test_baseline_has_105_parameters_numbered_once(base):
    assert sorted(base.parameters) == list(range(1, 106))
    assert {p.type for p in base.parameters.values()} <= {"D", "F", "C", "T"}
    for p in base.by_type("C"):
        assert p.bounds is not None, p.key
    for t in "DFT":
        assert all(p.bounds is None for p in base.by_type(t))


def test_baseline_thesis_values(base):
    # thesis 6.3.2 calibrated oil: 7.7 kbar and 0.35 % gas
    assert base["oil.K_oil"] == pytest.approx(7.7e8)
    assert base["oil.chi"] == pytest.approx(0.0035)
    # table 5.1 typing of a few parameters
    assert base.param(12).type == "D" and base.param(15).type == "T"
    assert [p.no for p in base.by_type("T")] == [15]
    # table 6.1 limits converted to SI (b, d per mm -> per m)
    assert base.param("piston_rebound.b").bounds == (0.0, 1.0e5)
    assert base.param("base_intake.d").bounds == (-1.0e5, 0.0)
    # names are unique within a group, access by number and name agree
    keys = [p.key for p in base.parameters.values()]
    assert len(keys) == len(set(keys))
    assert base[48] == base["piston_rebound.a"]
    assert base.param(52).value.endswith(".csv")


def test_baseline_active_valve_map_monotone(base):
    m = base.pq_map
    assert list(m.currents[[0, 2, -1]]) == [0.32, 0.9, 1.6]
    assert np.all(np.diff(m.flow, axis=1) > 0)  # rises with dp
    assert np.all(np.diff(m.flow, axis=0) <= 0)  # falls with current
    assert np.all(m.flow[:, 0] == 0)


def test_all_effect_switches_present(base):
    assert set(base.effects) == set(EFFECTS)


# ------------------------------------------------------------ rejections
def test_reject_missing_number(tmp_path, doc):
    doc["parameters"] = [p for p in doc["parameters"] if p["no"] != 7]
    rejected(write(tmp_path, doc), "no. 7", "K_oil", "missing number")


def test_reject_entry_without_number(tmp_path, doc):
    del entry(doc, 9)["no"]
    rejected(write(tmp_path, doc), "'nu'", "missing number 'no'")


def test_reject_duplicated_number(tmp_path, doc):
    doc["parameters"].append(copy.deepcopy(entry(doc, 20)))
    rejected(write(tmp_path, doc), "no. 20", "top_mount.R", "duplicated number")


@pytest.mark.parametrize("bad_no", [0, 106, -3, 52.5])
def test_reject_number_outside_range(tmp_path, doc, bad_no):
    entry(doc, 3)["no"] = bad_no
    msg = rejected(write(tmp_path, doc), "D_R", "outside 1..105")
    assert "no. 3 (geometry.D_R): missing number" in msg


def test_reject_unknown_type(tmp_path, doc):
    entry(doc, 8)["type"] = "X"
    rejected(write(tmp_path, doc), "no. 8", "rho_oil", "unknown type 'X'")


@pytest.mark.parametrize("value", [None, float("nan"), float("inf"), "fast", True])
def test_reject_missing_or_nonfinite_value(tmp_path, doc, value):
    entry(doc, 1)["value"] = value
    rejected(write(tmp_path, doc), "no. 1", "M_rod", "value")


def test_reject_deleted_value(tmp_path, doc):
    del entry(doc, 2)["value"]
    rejected(write(tmp_path, doc), "no. 2", "D_PT", "missing value")


def test_reject_value_outside_bounds(tmp_path, doc):
    entry(doc, 48)["value"] = 2.0e4  # table 6.1: a <= 10000
    rejected(write(tmp_path, doc), "no. 48", "piston_rebound.a", "outside bounds")


def test_reject_bounds_on_non_c_parameter(tmp_path, doc):
    entry(doc, 7)["bounds"] = [1e8, 2e9]
    rejected(write(tmp_path, doc), "no. 7", "K_oil", "bounds given on a type-F parameter")


def test_reject_c_parameter_without_bounds(tmp_path, doc):
    del entry(doc, 103)["bounds"]
    rejected(write(tmp_path, doc), "no. 103", "rod_friction.F_c", "has no bounds")


def test_reject_lower_not_below_upper(tmp_path, doc):
    entry(doc, 104)["bounds"] = [800.0, 0.0]
    rejected(write(tmp_path, doc), "no. 104", "rod_friction.F_s", "lower 800.0 >= upper 0.0")


@pytest.mark.parametrize("unit,why", [("bar", "unknown or not SI"), ("N", "expected the SI unit 'Pa'")])
def test_reject_unknown_or_wrong_unit(tmp_path, doc, unit, why):
    entry(doc, 10)["unit"] = unit
    rejected(write(tmp_path, doc), "no. 10", "P_sat", why)


def test_reject_unknown_effect_switch(tmp_path, doc):
    doc["effects"]["warp_drive"] = True
    rejected(write(tmp_path, doc), "effects.warp_drive", "unknown effect switch")


def test_reject_missing_map_file(tmp_path, doc):
    rejected(write(tmp_path, doc, map_src=None), "no. 52", "pq_map", "not found")


def test_reject_non_monotone_map(tmp_path, doc):
    rows = (CONF / "active_valve_baseline.csv").read_text().splitlines()
    # swap the flows at two dp points of the first current
    a, b = rows[5].split(","), rows[6].split(",")
    a[2], b[2] = b[2], a[2]
    rows[5], rows[6] = ",".join(a), ",".join(b)
    (tmp_path / "bad_map.csv").write_text("\n".join(rows) + "\n")
    entry(doc, 52)["value"] = "bad_map.csv"
    rejected(write(tmp_path, doc), "no. 52", "pq_map", "not monotone")


def test_reject_map_with_wrong_columns(tmp_path, doc):
    text = (CONF / "active_valve_baseline.csv").read_text().replace("dp [Pa]", "dp [bar]")
    (tmp_path / "m.csv").write_text(text)
    entry(doc, 52)["value"] = "m.csv"
    rejected(write(tmp_path, doc), "no. 52", "header", repr(list(MAP_COLUMNS)))


def test_errors_are_collected_not_first_only(tmp_path, doc):
    entry(doc, 1)["type"] = "Q"
    entry(doc, 2)["unit"] = "mm"
    doc["effects"]["bogus"] = False
    with pytest.raises(DesignError) as ei:
        load(write(tmp_path, doc))
    assert len(ei.value.errors) == 3


# ------------------------------------------------------------ round trip
def test_dump_load_round_trip_is_identity(tmp_path, base):
    out = base.dump(tmp_path / "sub" / "copy.yaml")
    again = load(out, map_dirs=[CONF])  # the map stays in conf/design: an explicitly allowed folder
    assert again == base
    assert again.hash() == base.hash()
    assert all(again.param(n) == base.param(n) for n in range(1, 106) if n != 52)
    # the baseline file itself is in dump format: dumping it reproduces it byte for byte
    assert base.dumps(CONF) == BASELINE.read_text()
    # dumping elsewhere keeps the P/Q map reachable and unchanged
    assert again.pq_map == base.pq_map


def test_hash_stable_and_content_sensitive(base):
    assert base.hash() == load(BASELINE).hash()
    assert base.with_overrides({"oil.chi": 0.004}).hash() != base.hash()
    assert base.with_overrides({"effects.jet_force": False}).hash() != base.hash()
    # a map with the same data under another name hashes the same
    assert base.with_overrides({52: "active_valve_alternative.csv"}).hash() != base.hash()


# ------------------------------------------------------------ overrides
def test_overrides_do_not_mutate_original(base):
    before = base.hash()
    v = base.with_overrides({"piston_rebound.a": 350.0, 12: 0.005, "constants.zeta": 1.0,
                             "effects.rod_friction": False})
    assert base.hash() == before
    assert base["piston_rebound.a"] == 300.0 and v["piston_rebound.a"] == 350.0
    assert v["oil.chi"] == 0.005 and v["constants.zeta"] == 1.0
    assert v.effects["rod_friction"] is False and base.effects["rod_friction"] is True
    with pytest.raises(TypeError):
        v.effects["rod_friction"] = True  # read-only mapping


def test_override_unknown_name_rejected(base):
    with pytest.raises(DesignError, match="unknown parameter 'piston_rebound.zz'"):
        base.with_overrides({"piston_rebound.zz": 1.0})
    with pytest.raises(DesignError, match="unknown effect 'teleport'"):
        base.with_overrides({"effects.teleport": True})
    with pytest.raises(DesignError, match="unknown constant"):
        base.with_overrides({"constants.nope": 1.0})


def test_override_is_validated(base):
    with pytest.raises(DesignError, match=r"no\. 49 \(piston_rebound\.b\).*outside bounds"):
        base.with_overrides({49: 2.0e5})


def test_ambiguous_bare_name_rejected(base):
    with pytest.raises(KeyError):
        base.param("a")  # four valves have an 'a'
    assert base["K_oil"] == base[7]


# ------------------------------------------------------------ fuzzing
NUMS = sorted(BY_NUMBER)
FIELDS = ["no", "name", "type", "value", "unit", "bounds", "group", "delete"]


@functools.cache
def _baseline_doc() -> dict:
    """The baseline document, parsed once for the fuzzer (each example corrupts a deep copy)."""
    return yaml.safe_load(BASELINE.read_text())


@st.composite
def corruption(draw):
    no = draw(st.sampled_from(NUMS))
    field = draw(st.sampled_from(FIELDS))
    if field == "no":
        bad = draw(st.one_of(st.integers(-1000, 0), st.integers(106, 10**6), st.sampled_from(NUMS).filter(lambda n: n != no),
                             st.text(max_size=5), st.floats(allow_nan=True)))
    elif field == "name":
        bad = draw(st.text(min_size=1, max_size=12).filter(lambda s: s != BY_NUMBER[no].name))
    elif field == "type":
        bad = draw(st.one_of(st.text(max_size=3).filter(lambda s: s not in "DFCT" or s == ""), st.integers(), st.none()))
    elif field == "value":
        if BY_NUMBER[no].kind == "table":
            bad = draw(st.one_of(st.text(min_size=1, max_size=8).map(lambda s: "missing_" + s + ".csv"), st.none(), st.floats()))
        else:
            bad = draw(st.one_of(st.none(), st.text(max_size=6), st.sampled_from([math.nan, math.inf, -math.inf]),
                                 st.booleans(), st.lists(st.none(), max_size=2), st.dictionaries(st.text(max_size=2), st.integers(), max_size=1)))
    elif field == "unit":
        bad = draw(st.text(max_size=6).filter(lambda s: s != BY_NUMBER[no].unit))
    elif field == "bounds":
        bad = draw(st.one_of(st.just([1.0, 0.0]), st.text(max_size=4), st.lists(st.floats(), min_size=3, max_size=3),
                             st.just([-1e30, -1e29]), st.just([1e29, 1e30])))
    elif field == "group":
        bad = draw(st.text(max_size=8).filter(lambda s: s != BY_NUMBER[no].group))
    else:
        bad = draw(st.sampled_from(["no", "name", "type", "value", "unit", "source", "symbol", "group", "description"]))
    return no, field, bad


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(corruption())
def test_random_single_field_corruption_is_rejected(tmp_path_factory, c):
    no, field, bad = c
    doc = copy.deepcopy(_baseline_doc())
    e = entry(doc, no)
    if field == "delete":
        del e[bad]
    elif field == "bounds" and BY_NUMBER[no].kind == "vector" and isinstance(bad, list) and len(bad) == 2:
        e["bounds"] = [[bad[0]] * 5, [bad[1]] * 5]
    else:
        e[field] = bad
    text = yaml.dump(doc, Dumper=_Dumper, sort_keys=False)
    try:
        loads(text, base_dir=CONF, where="fuzz.yaml")
    except DesignError as err:
        assert "fuzz.yaml" in str(err)
    else:
        raise AssertionError(f"accepted corruption {c}")


def test_design_pickles_for_process_pools(base):
    """Designs cross process boundaries (discrepancy record pool): same hash, same text, still read-only."""
    import pickle

    d = base.with_overrides({"effects.oil_thermal": True, "piston_rebound.a": 1.1 * base["piston_rebound.a"]})
    e = pickle.loads(pickle.dumps(d))
    assert e.hash() == d.hash() and e.dumps() == d.dumps() and e.hash() != base.hash()
    with pytest.raises(TypeError):
        e.effects["oil_thermal"] = False


def test_design_is_immutable_so_its_cached_hash_and_pack_cannot_go_stale(base):
    """Design caches its hash and packed parameter vector (Design.memo): every
    route that could change a design after construction must be closed."""
    import pickle
    from types import MappingProxyType

    from dampertwin.model.params import pack

    h, p1 = base.hash(), pack(base, current=1.0)
    # the constructor copies plain dicts: changing the caller's dict afterwards changes nothing
    params = dict(base.parameters)
    d = Design(base.name, base.description, params, dict(base.constants), dict(base.effects), base.pq_map,
               effect_params=dict(base.effect_params))
    assert d.hash() == h
    params[1] = params[2]
    assert isinstance(d.parameters, MappingProxyType) and d.parameters[1] == base.parameters[1]
    assert d.hash() == h
    with pytest.raises(TypeError):
        d.constants["zeta"] = None
    for a in (base.pq_map.flow, base.pq_map.currents, base.pq_map.dps):
        with pytest.raises(ValueError, match="read-only"):
            a[0] = 1.0
    q = pickle.loads(pickle.dumps(base))  # process pools
    assert not q.pq_map.flow.flags.writeable and q.hash() == h
    # pack hands out a fresh, writable vector: the caller's edits do not reach the cache
    p1[:] = -1.0
    p2 = pack(base, current=1.0)
    assert p2.flags.writeable and np.array_equal(p2, pack(load(BASELINE), current=1.0))
    # the cache is keyed by the effect switches
    on = pack(base, current=1.0, effects={"rod_friction": not base.effects["rod_friction"]})
    assert not np.array_equal(on, p2)
