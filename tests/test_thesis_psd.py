"""scripts/thesis_psd.py (issue 40 items 2-3, the 200 Hz cells of tables 6.6 / 7.2): the tilted
input is the protocol's signal when untilted and has the slope it claims when tilted, the
low-dp map diagnostic changes only what it says, and the committed page is the committed
result's (no hand edits). Fast: no simulation."""

from __future__ import annotations

import importlib.util
import json
import math
import sys

import numpy as np
from scipy import signal

from conftest import ROOT
from dampertwin.design import load
from dampertwin.protocols import load_protocol
from dampertwin.protocols.signals import band_noise


def _load(name):
    sys.path.insert(0, str(ROOT / "scripts"))
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


tp = _load("thesis_psd")
PROTO = load_protocol(ROOT / "conf" / "test" / "random.yaml")
RATE = max(PROTO["rate"], 2000.0)


def _noise(k):
    return tp.shaped_noise(PROTO["bands"], PROTO["duration"], 17, RATE, k)


def _acc_db(ex, fc):
    """Input acceleration PSD [dB] in a 10 Hz band around fc."""
    f, P = signal.welch(ex.value, fs=RATE, nperseg=int(RATE / 2), noverlap=int(RATE / 4))
    return 10 * math.log10(tp.band_mean(f, P * (2 * math.pi * f) ** 4, fc))


def test_untilted_input_is_the_protocols_signal():
    a, b = _noise(0.0), band_noise(PROTO["bands"], PROTO["duration"], 17, RATE)
    np.testing.assert_array_equal(a.value, b.value)
    np.testing.assert_array_equal(a.rate, b.rate)


def test_tilt_sets_the_tails_slope_and_keeps_its_level_at_the_reference():
    flat_x, flat_a = _noise(0.0), _noise(4.0)
    # flat displacement: acceleration rises by 40 log10(3/2) = 7.0 dB from 200 to 300 Hz; flat acceleration: 0
    assert abs(_acc_db(flat_x, 300) - _acc_db(flat_x, 200) - 40 * math.log10(1.5)) < 1.0
    assert abs(_acc_db(flat_a, 300) - _acc_db(flat_a, 200)) < 1.0
    assert abs(_acc_db(flat_a, 300) - _acc_db(flat_x, 300)) < 1.0
    # the body band (below 25 Hz) is untouched
    f, Px = signal.welch(flat_x.value, fs=RATE, nperseg=int(RATE / 2))
    _, Pa = signal.welch(flat_a.value, fs=RATE, nperseg=int(RATE / 2))
    body = (f > 2) & (f < 24)
    np.testing.assert_allclose(Pa[body], Px[body], rtol=0.05)


def test_low_dp_map_widens_only_the_low_current_bleed_and_stays_a_valid_map():
    d = load(ROOT / "conf" / "design" / "baseline.yaml")
    pq = d.pq_map
    assert np.array_equal(tp.low_dp_map(pq, 1.0).flow, pq.flow)
    new = tp.low_dp_map(pq, 20.0)
    j = int(np.argmin(abs(pq.dps - tp.MAP_DP)))
    lo, hi = int(np.argmin(pq.currents)), int(np.argmax(pq.currents))
    assert math.isclose(new.flow[lo, j], 20.0 * pq.flow[lo, j])
    np.testing.assert_array_equal(new.flow[hi], pq.flow[hi])
    assert np.all(new.flow >= pq.flow)
    d.with_pq_map(new, "low_dp.csv", "test")  # the design's map checks (monotone, positive) pass


def test_published_current_dependence_is_the_tables_arithmetic():
    import yaml

    pub = tp.published(yaml.safe_load((ROOT / "conf" / "thesis" / "published.yaml").read_text()))
    assert pub["6.6 simulated"]["current dependence"] == {"200": -10.5, "300": -10.1}
    assert pub["6.6 measured"]["200 - 300"]["1.6"] == -2.4


def test_committed_page_is_the_committed_results():
    doc = json.loads((ROOT / "results" / "thesis_psd.json").read_text())
    assert (ROOT / "docs" / "validation" / "thesis-psd.md").read_text() == tp.page(doc)
    assert (ROOT / "docs" / "validation" / "thesis_psd.png").stat().st_size > 10_000
