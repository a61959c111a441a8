"""scripts/thesis_comparison.py (issue 40 item 1): the transcription file's
structure, the difference arithmetic and its sign / base convention, the
thesis' own Diff. rules. Fast: no simulation."""

from __future__ import annotations

import importlib.util
import math

import pytest

from conftest import ROOT
from dampertwin.design import yaml_load_file

PUB = yaml_load_file(ROOT / "conf" / "thesis" / "published.yaml")


def _load(name):
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


tc = _load("thesis_comparison")
VARIANTS = {p.stem for p in (ROOT / "conf" / "variant").glob("*.yaml")}


@pytest.mark.parametrize("key,cols,n", [("table_6_5", ("rebound", "compression"), 10),
                                        ("table_6_6", ("f200", "f300"), 10),
                                        ("table_7_1", ("rebound", "compression"), 3),
                                        ("table_7_2", ("f200", "f300"), 3)])
def test_transcribed_tables_are_complete_and_referenced(key, cols, n):
    tab = PUB[key]
    assert {"table", "page", "line"} <= set(tab["ref"]), key
    assert tab["diff_rule"] in ("pct_signed_m", "pct_abs_m", "db_abs")
    assert [r["no"] for r in tab["rows"]] == list(range(1, n + 1))
    for r in tab["rows"]:
        assert r["case"] in VARIANTS, (key, r)
        assert yaml_load_file(ROOT / "conf" / "variant" / f"{r['case']}.yaml")["current"] == r["current"]
        for c in cols:
            assert {"s", "m", "diff"} == set(r[c]) and all(isinstance(r[c][k], (int, float)) for k in r[c])
            if key in ("table_6_6", "table_7_2"):
                assert r[c]["s"] < 0 and r[c]["m"] < 0  # dB re 1 g^2/Hz: all printed levels are negative
    if cols[0] == "rebound":  # compression peaks print negative in every row
        assert all(r["compression"]["s"] < 0 and r["compression"]["m"] < 0 for r in tab["rows"])


def test_transcription_spot_values():
    """A few cells against the thesis text (catches a shifted row or column)."""
    t65 = {r["no"]: r for r in PUB["table_6_5"]["rows"]}
    assert t65[2]["rebound"] == {"s": -4.7, "m": -1.3, "diff": -247.4}
    assert t65[9]["compression"] == {"s": -16.1, "m": -8.4, "diff": -92.1}
    t66 = {r["no"]: r for r in PUB["table_6_6"]["rows"]}
    assert t66[7]["f200"] == {"s": -1.9, "m": -6.2, "diff": 4.3}
    assert PUB["table_7_1"]["rows"][0]["rebound"] == {"s": 15.8, "m": 17.9, "diff": 11.8}
    assert PUB["table_7_2"]["rows"][2]["f300"] == {"s": -23.4, "m": -19.1, "diff": 4.4}


def test_difference_sign_and_base():
    """diff % = (project - thesis) / |thesis| x 100: the thesis value is the
    base (11 vs 10 is +10 %, not +9.09 %), and the sign follows project -
    thesis for negative peaks too (-9 vs -10 is +10 %: smaller magnitude)."""
    assert tc.pct_diff(11.0, 10.0) == pytest.approx(10.0)
    assert tc.pct_diff(10.0, 11.0) == pytest.approx(-100.0 / 11.0)
    assert tc.pct_diff(-9.0, -10.0) == pytest.approx(10.0)
    assert tc.pct_diff(-11.0, -10.0) == pytest.approx(-10.0)
    assert tc.pct_diff(5.6, -4.7) == pytest.approx((5.6 + 4.7) / 4.7 * 100)
    assert tc.db_diff(-16.0, -4.0) == pytest.approx(-12.0)
    assert tc.agrees(-15.0, "%") and not tc.agrees(15.01, "%")
    assert tc.agrees(2.0, "dB") and not tc.agrees(-2.01, "dB")


def test_compare_rows_on_a_tiny_case():
    tab = {"rows": [{"no": 1, "case": "baseline_1.6", "current": 1.6,
                     "rebound": {"s": 8.0, "m": 10.0, "diff": 20.0}, "compression": {"s": -16.0, "m": -9.0, "diff": 0}}]}
    proj = {("baseline_1.6", "rebound"): 9.0, ("baseline_1.6", "compression"): -12.0}
    row = tc.compare_rows(tab, proj, ("rebound", "compression"), "%")[0]
    assert row["rebound"]["diff"] == pytest.approx(12.5) and row["rebound"]["agree"]
    assert row["compression"]["diff"] == pytest.approx(25.0) and not row["compression"]["agree"]


def test_thesis_rules_reproduce_printed_rows():
    """The thesis' own conventions, checked on printed rows: table 6.5 row 1
    (m - s) / m; table 7.1 row 1 compression (m - s) / |m|; table 6.6 |s - m|."""
    assert tc.thesis_rule("pct_signed_m", -16.9, -9.2) == pytest.approx(-83.7, abs=0.05)
    assert tc.thesis_rule("pct_abs_m", -9.1, -9.9) == pytest.approx(-8.08, abs=0.01)
    assert tc.thesis_rule("pct_signed_m", -9.1, -9.9) == pytest.approx(8.08, abs=0.01)
    assert tc.thesis_rule("db_abs", -6.3, -5.7) == pytest.approx(0.6)
    lo, hi = tc.rule_interval("db_abs", -6.0, -5.95, 0.05)
    assert lo == 0.0 and hi == pytest.approx(0.15)
    with pytest.raises(ValueError):
        tc.thesis_rule("nope", 1.0, 2.0)


def test_thesis_arithmetic_finds_the_one_sign_inconsistency():
    checks = tc.check_thesis_arithmetic(PUB)
    assert len(checks) == 52
    bad = [(c["table"], c["no"], c["column"]) for c in checks if not c["consistent"]]
    assert bad == [("6.5", 3, "compression")]


def test_event_delay_functions():
    import numpy as np

    t = np.linspace(0.0, 1.0, 1001)
    lift = np.where((t > 0.2) & (t < 0.5), 1e-4, 0.0)
    ups, downs = tc.crossings(t, lift, 1e-6)
    assert ups.tolist() == pytest.approx([0.201]) and downs.tolist() == pytest.approx([0.5])
    assert tc.next_after(ups, downs, 0.0) == pytest.approx(0.299)
    assert math.isnan(tc.next_after(ups, downs, 0.3))


def test_committed_outputs_match_the_transcription():
    """The committed JSON was made from this transcription (its thesis
    columns equal the file's simulated columns)."""
    import json

    res = json.loads((ROOT / "results" / "thesis_comparison.json").read_text())
    for key in ("table_6_5", "table_6_6", "table_7_1", "table_7_2"):
        cols = ("rebound", "compression") if key in ("table_6_5", "table_7_1") else ("f200", "f300")
        for got, want in zip(res[key], PUB[key]["rows"], strict=True):
            for c in cols:
                assert got[c]["thesis"] == want[c]["s"]
                fn = tc.pct_diff if cols[0] == "rebound" else tc.db_diff
                assert got[c]["diff"] == pytest.approx(fn(got[c]["project"], want[c]["s"]), abs=1e-4)
    assert (ROOT / "docs" / "validation" / "thesis-comparison.md").is_file()
