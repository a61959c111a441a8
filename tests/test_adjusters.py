"""Clicker adjusters (design key ``adjusters:`` / ``setting:``): parsing and
validation, ``Design.at_setting``, a design without adjusters unchanged, a
record's setting, the CLI, and the physics of a rebound bleed click."""

from __future__ import annotations

import copy
import math
import pickle
from pathlib import Path

import numpy as np
import pytest
import yaml

from dampertwin import Excitation, simulate
from dampertwin.cli import main
from dampertwin.design import DesignError, load, loads
from dampertwin.design.adjusters import design_for_record, format_adjusters, without_adjusters
from dampertwin.design.description import _Dumper
from dampertwin.importer import MappingError, import_measurement
from dampertwin.io import read_meta
from dampertwin.model.params import pack

from conftest import BASELINE, ROOT

CONF = BASELINE.parent
# clicks counted out from fully closed: the bleed area rises, the preload falls
REBOUND = [0.4e-6, 0.6e-6, 0.8e-6, 1.0e-6, 1.3e-6, 1.6e-6, 2.0e-6, 2.5e-6]
COMPRESSION = [450.0, 400.0, 350.0, 300.0, 250.0, 200.0, 150.0]


@pytest.fixture(scope="module")
def base():
    return load(BASELINE)


def table(doc: dict) -> dict:
    """The baseline document with a rebound bleed and a compression preload adjuster."""
    doc = copy.deepcopy(doc)
    reb = next(p for p in doc["parameters"] if p["no"] == 38)["value"]
    comp = next(p for p in doc["parameters"] if p["no"] == 82)["value"]
    doc["adjusters"] = {
        "rebound": {"valve": "piston_rebound", "parameter": "A_bleed", "unit": "m^2", "clicks": list(REBOUND),
                    "source": "bleed needle, 8 clicks (test table)"},
        "compression": {"valve": "base_compression", "parameter": "F_preload", "unit": "N",
                        "clicks": list(COMPRESSION), "source": "spring preload, 7 clicks (test table)"},
    }
    doc["setting"] = {"rebound": REBOUND.index(reb), "compression": COMPRESSION.index(comp)}
    return doc


@pytest.fixture(scope="module")
def base_doc() -> dict:
    return yaml.safe_load(BASELINE.read_text())


@pytest.fixture()
def doc(base_doc) -> dict:
    return table(base_doc)


def write(tmp_path: Path, doc: dict, name: str = "adjustable.yaml") -> Path:
    (tmp_path / "active_valve_baseline.csv").write_text((CONF / "active_valve_baseline.csv").read_text())
    p = tmp_path / name
    p.write_text(yaml.dump(doc, Dumper=_Dumper, sort_keys=False))
    return p


@pytest.fixture(scope="module")
def adjustable(base_doc, tmp_path_factory):
    return load(write(tmp_path_factory.mktemp("adj"), table(base_doc)))


# ------------------------------------------------------------------ parsing
def test_table_parses_and_the_setting_is_the_parameter_value(adjustable, base):
    a = adjustable
    assert list(a.adjusters) == ["rebound", "compression"]
    assert a.adjusters["rebound"].key == "piston_rebound.A_bleed" and a.adjusters["rebound"].no == 38
    assert a.adjusters["compression"].clicks == tuple(COMPRESSION)
    assert a.setting == {"rebound": REBOUND.index(base["piston_rebound.A_bleed"]),
                         "compression": COMPRESSION.index(base["base_compression.F_preload"])}
    # the dump carries the table and the setting and loads back equal; so does a pickle
    again = loads(a.dumps(a.path.parent), base_dir=a.path.parent)
    assert again == a and again.setting == a.setting
    assert pickle.loads(pickle.dumps(a)) == a and pickle.loads(pickle.dumps(a)).adjusters == a.adjusters
    lines = "\n".join(format_adjusters(a))
    assert "rebound: piston_rebound.A_bleed (no. 38) [m^2], 8 clicks, at click 3" in lines


def _set(path, value):
    def f(doc):
        d = doc
        for k in path[:-1]:
            d = d[k]
        d[path[-1]] = value
    return f


def _drop(path):
    def f(doc):
        d = doc
        for k in path[:-1]:
            d = d[k]
        del d[path[-1]]
    return f


BAD = {
    "unknown valve": (_set(["adjusters", "rebound", "valve"], "piston"), "adjusters.rebound.valve: 'piston'"),
    "bleed on a disc valve": (_set(["adjusters", "rebound", "valve"], "piston_intake"),
                              "adjusters.rebound.parameter: 'A_bleed'; an adjuster on 'piston_intake' moves one "
                              "of F_preload"),
    "unit not SI": (_set(["adjusters", "rebound", "unit"], "mm^2"), "adjusters.rebound.unit: 'mm^2'"),
    "unknown field": (_set(["adjusters", "rebound", "step"], 1), "adjusters.rebound: unknown field 'step'"),
    "missing field": (_drop(["adjusters", "rebound", "source"]), "adjusters.rebound: missing field 'source'"),
    "unknown adjuster": (_set(["adjusters", "high_speed"], {}), "adjusters.high_speed: unknown adjuster"),
    "empty clicks": (_set(["adjusters", "rebound", "clicks"], []), "adjusters.rebound.clicks: expected a non-empty"),
    "non-finite click": (_set(["adjusters", "rebound", "clicks"], [1e-6, float("nan")]),
                         "adjusters.rebound.clicks: expected a non-empty list of finite"),
    "negative area": (_set(["adjusters", "rebound", "clicks"], [-1e-6, 1e-6]),
                      "adjusters.rebound.clicks: -1e-06 m^2; expected >= 0"),
    "not monotonic": (_set(["adjusters", "rebound", "clicks"], [1e-6, 0.8e-6, 1.2e-6]),
                      "adjusters.rebound.clicks: [1e-06, 8e-07, 1.2e-06]; expected values that rise strictly"),
    "preload rising": (_set(["adjusters", "compression", "clicks"], [200.0, 300.0]),
                       "adjusters.compression.clicks: [200.0, 300.0]; expected values that fall strictly"),
    "click outside the C bounds": (_set(["adjusters", "compression", "clicks"], [700.0, 300.0]),
                                   "adjusters.compression.clicks: 700.0 N outside the bounds"),
    "same parameter twice": (_set(["adjusters", "compression"], {
        "valve": "piston_rebound", "parameter": "A_bleed", "unit": "m^2", "clicks": REBOUND, "source": "x"}),
        "adjusters.compression: moves piston_rebound.A_bleed, which adjusters.rebound moves already"),
    "setting out of range": (_set(["setting", "rebound"], 8), "setting.rebound: 8; expected a click number 0 .. 7"),
    "setting not an integer": (_set(["setting", "rebound"], 3.0), "setting.rebound: 3.0; expected a click number"),
    "setting disagrees with the value": (_set(["setting", "rebound"], 4),
                                         "setting.rebound: click 4 is 1.3e-06 m^2, but no. 38"),
    "value is no click": (lambda d: (_drop(["setting", "rebound"])(d),
                                     _set(["adjusters", "rebound", "clicks"], [0.5e-6, 2e-6])(d)),
                          "adjusters.rebound: no. 38 (piston_rebound.A_bleed) = 1e-06 m^2 is none of the clicks"),
    "setting of no adjuster": (_set(["setting", "bump"], 1), "setting.bump: no such adjuster"),
    "setting without a table": (_drop(["adjusters"]), "setting: given but the design has no 'adjusters:' table"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_table_names_file_and_key(case, doc, tmp_path):
    mutate, needle = BAD[case]
    mutate(doc)
    path = write(tmp_path, doc)
    with pytest.raises(DesignError) as ei:
        load(path)
    msg = str(ei.value)
    assert f"{path}: " in msg and needle in msg, msg


# ------------------------------------------------------------------ at_setting
def test_at_setting_moves_exactly_the_named_parameters(adjustable):
    a = adjustable
    b = a.at_setting({"rebound": 6})
    assert b.setting == {"rebound": 6, "compression": a.setting["compression"]}
    assert b["piston_rebound.A_bleed"] == REBOUND[6]
    changed = [n for n in a.parameters if a.parameters[n] != b.parameters[n]]
    assert changed == [38]
    assert dict(b.constants) == dict(a.constants) and dict(b.effects) == dict(a.effects)
    c = a.at_setting({"rebound": 0, "compression": 6})
    assert [n for n in a.parameters if a.parameters[n] != c.parameters[n]] == [38, 82]
    assert c["base_compression.F_preload"] == COMPRESSION[6]
    # the override machinery: hash, dump and packed vector follow the values
    assert b.hash() == a.with_overrides({"piston_rebound.A_bleed": REBOUND[6]}).hash() != a.hash()
    assert loads(b.dumps(a.path.parent), base_dir=a.path.parent).setting == b.setting
    pa, pb = pack(a), pack(b)
    assert np.flatnonzero(pa != pb).size == 1 and REBOUND[6] in pb and REBOUND[6] not in pa
    assert a.at_setting(a.setting) is a


def test_at_setting_rejects_unknown_adjusters_and_clicks(adjustable, base):
    with pytest.raises(DesignError, match=r"setting\.rebound: click 8; expected a click number 0 \.\. 7"):
        adjustable.at_setting({"rebound": 8})
    with pytest.raises(DesignError, match=r"setting\.rebound: click -1"):
        adjustable.at_setting({"rebound": -1})
    with pytest.raises(DesignError, match=r"setting\.rebound: click True"):
        adjustable.at_setting({"rebound": True})
    with pytest.raises(DesignError, match=r"setting\.bump: design 'baseline' has no such adjuster"):
        adjustable.at_setting({"bump": 1})
    with pytest.raises(DesignError, match="the design has no 'adjusters:' table"):
        base.at_setting({"rebound": 1})


def test_an_override_between_clicks_is_refused_and_one_on_a_click_moves_the_setting(adjustable):
    with pytest.raises(DesignError, match=r"adjusters\.rebound: no\. 38 .* is none of the clicks"):
        adjustable.with_overrides({"piston_rebound.A_bleed": 1.1e-6}, source="variant.yaml")
    assert adjustable.with_overrides({"piston_rebound.A_bleed": REBOUND[1]}).setting["rebound"] == 1
    # without the table the value is free again (to calibrate one setting), and the design is the baseline
    free = without_adjusters(adjustable.at_setting({"rebound": 6}))
    assert free.adjusters == {} and free["piston_rebound.A_bleed"] == REBOUND[6]
    assert free.with_overrides({"piston_rebound.A_bleed": 1.1e-6})["piston_rebound.A_bleed"] == 1.1e-6
    assert without_adjusters(adjustable) == load(BASELINE)


def test_without_adjusters_the_design_is_unchanged(base, adjustable):
    """The shipped baseline (no adjusters) dumps byte for byte to its file; the
    table adds only its own sections: same hash, same packed vector, same dump without them."""
    assert base.adjusters == {} and base.setting == {}
    text = base.dumps(BASELINE.parent)
    assert text == BASELINE.read_text()
    assert "adjusters" not in yaml.safe_load(text) and "setting" not in yaml.safe_load(text)
    assert adjustable.hash() == base.hash()
    assert np.array_equal(pack(adjustable), pack(base)) and np.array_equal(pack(base), pack(load(BASELINE)))
    doc = yaml.safe_load(adjustable.dumps(adjustable.path.parent))  # the P/Q map beside it: the same name
    assert list(doc)[-2:] == ["adjusters", "setting"]
    del doc["adjusters"], doc["setting"]
    assert yaml.dump(doc, Dumper=_Dumper, sort_keys=False, width=100, allow_unicode=True) == text


# ------------------------------------------------------------------ records
def test_a_record_names_its_setting(adjustable, tmp_path):
    mapping = yaml.safe_load((ROOT / "examples" / "mapping.yaml").read_text())
    mapping["setting"] = {"rebound": 6, "compression": 1}
    out = import_measurement(ROOT / "examples" / "rig_monosine.csv", mapping,
                             tmp_path / "own" / "monosine" / "r6_c1.parquet")
    meta = read_meta(out)
    assert meta["setting"] == {"rebound": 6, "compression": 1}
    d = design_for_record(adjustable, meta, where=str(out))
    assert d.setting == {"rebound": 6, "compression": 1}
    assert d["piston_rebound.A_bleed"] == REBOUND[6] and d["base_compression.F_preload"] == COMPRESSION[1]
    assert design_for_record(adjustable, {"protocol": "monosine"}) is adjustable  # names no setting
    with pytest.raises(DesignError) as ei:
        design_for_record(adjustable, {"setting": {"rebound": 9}}, where="rec.parquet")
    assert "rec.parquet (setting of the record" in str(ei.value) and "setting.rebound: click 9" in str(ei.value)
    only_rebound = adjustable.with_overrides({})  # a copy; then a design with the rebound adjuster only
    doc = yaml.safe_load(only_rebound.dumps(only_rebound.path.parent))
    del doc["adjusters"]["compression"], doc["setting"]["compression"]
    with pytest.raises(DesignError, match=r"rec\.parquet .*setting\.compression: design 'baseline' has no such "
                                          r"adjuster; expected one of rebound"):
        design_for_record(loads(yaml.dump(doc), base_dir=adjustable.path.parent), meta, where="rec.parquet")


@pytest.mark.parametrize("bad", [{"rebound": -1}, {"rebound": 2.0}, {"bump": 1}, [3, 5], {}])
def test_import_rejects_a_bad_setting(bad, tmp_path):
    mapping = yaml.safe_load((ROOT / "examples" / "mapping.yaml").read_text())
    mapping["setting"] = bad
    with pytest.raises(MappingError, match=r"mapping: setting: .*expected \{rebound: R, compression: C\}"):
        import_measurement(ROOT / "examples" / "rig_monosine.csv", mapping, tmp_path / "monosine" / "x.parquet")
    assert not (tmp_path / "monosine" / "x.parquet").exists()


# ------------------------------------------------------------------ CLI
def test_design_show_and_check_print_the_table(adjustable, doc, tmp_path, capsys):
    assert main(["design", "show", str(adjustable.path)]) == 0
    out = capsys.readouterr().out
    assert "adjusters (click 0 = fully closed, counted out):" in out and ">3:1e-06" in out
    assert main(["design", "check", str(adjustable.path)]) == 0
    assert "adjuster rebound: piston_rebound.A_bleed 8 clicks at 3" in capsys.readouterr().out
    doc["setting"]["compression"] = 0
    bad = write(tmp_path, doc, "bad.yaml")
    assert main(["design", "check", str(bad)]) == 1
    assert f"{bad}: setting.compression: click 0 is 450.0 N" in capsys.readouterr().err


# ------------------------------------------------------------------ physics
def _rebound_force(design, v=0.05) -> float:
    """Mean rod force [N] over the last 20 ms of a 0.1 s constant-velocity rebound stroke (damper rig, 1.6 A)."""
    r = simulate(design, Excitation.constant_rate(v, 0.1), "damper", current=1.6)
    assert r.ok
    return float(np.mean(r["rod force [N]"][-200:]))


def test_a_larger_rebound_bleed_click_lowers_the_low_speed_rebound_force(adjustable):
    """The bleed is an orifice in parallel with the shim-stack opening (model/valves.py valve_flow,
    THESIS-ERRATA 25: G1 = Cq A_f + Cq_b A_bleed): at 0.05 m/s,
    below the stack's opening, more bleed area means a lower pressure drop, a lower rebound force."""
    f3, f6 = _rebound_force(adjustable.at_setting({"rebound": 3})), _rebound_force(adjustable.at_setting({"rebound": 6}))
    assert f3 > 0 and math.isfinite(f6)
    assert f6 < 0.8 * f3, (f3, f6)


def test_a_simulated_record_names_the_setting_it_was_simulated_at(adjustable, tmp_path):
    from dampertwin.simulate_test import simulate_test

    d = adjustable.at_setting({"rebound": 5, "compression": 2})
    path = d.dump(adjustable.path.parent / "r5_c2.yaml")  # beside the P/Q map
    pq, _ = simulate_test(path, "compliance", tmp_path / "sim", case="v0.4_I1.6", conf=ROOT / "conf")
    meta = read_meta(pq)
    assert meta["setting"] == {"rebound": 5, "compression": 2}
    assert design_for_record(adjustable, meta, where=str(pq)) == load(path)
    assert "setting" not in read_meta(simulate_test(BASELINE, "compliance", tmp_path / "base", case="v0.4_I1.6",
                                                    conf=ROOT / "conf")[0])
