"""The library of candidate physical effects (issue 10, items 5, 6): the
design section ``effect_parameters:``, and per effect the thesis lacks
(a) off -> outputs bit-identical whatever its parameters (and equal to the
    model without it, a stored short run of the pre-library code),
(b) on at its ``typical`` magnitude -> the KPI of ``EFFECTS_LIBRARY`` moves in
    the documented direction,
(c) regularised terms do not chatter (step count and rejections bounded).
Short runs (2 cycles), so the file stays well under two minutes."""

from __future__ import annotations

import sys

import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from dampertwin import Excitation, simulate
from dampertwin.design import EFFECT_PARAMETERS, EFFECTS, DesignError, load, loads
from dampertwin.model import layout as L
from dampertwin.model.params import EFFECT_INDEX, EFFECTS_LIBRARY, effects_table, pack

from conftest import BASELINE

ROOT = Path(__file__).resolve().parents[1]
HEAD_REF = ROOT / "tests" / "reference" / "effects_off_reference.npz"
NEW = sorted(n for n, r in EFFECTS_LIBRARY.items() if not r.thesis)
F13, F16 = 13.0, 16.0


@pytest.fixture(scope="module")
def base():
    return load(BASELINE)


def _sine(f, cycles=2, amplitude=0.005):
    return Excitation.sine(duration=cycles / f, amplitude=amplitude, frequency=f)


def _on(design, effect, **extra):
    """The design with ``effect`` switched on at its typical magnitude."""
    ov = {e.key: e.typical for e in design.effect_parameters(effect)}
    ov.update(extra)
    ov[f"effects.{effect}"] = True
    return design.with_overrides(ov)


def _far(e):
    """A value far from the entry's own, inside its bounds / range."""
    if e.bounds is not None:
        lo, hi = e.bounds
        return hi if abs(e.value - hi) > abs(e.value - lo) else lo
    rng = EFFECT_PARAMETERS[e.key][1]
    return next(v for v in (e.value * 7.0, e.value * 3.0, e.value * 1.3, e.value * 0.3) if rng.contains(v))


# ------------------------------------------------------------ design section
def test_effect_parameters_api(base):
    """Keys "<effect>.<name>", entries with key/effect/name/value/type/bounds/
    typical/unit; every new effect has its parameters, C ones with bounds."""
    assert base["active_valve_lag.tau"] == base.effect_parameters("active_valve_lag")[0].value
    for name in NEW:
        entries = base.effect_parameters(name)
        assert entries, name
        for e in entries:
            assert e.key == f"{e.effect}.{e.name}" and e.effect == name
            assert e.unit == EFFECT_PARAMETERS[e.key][0]
            assert e.type in ("C", "F")
            if e.type == "C":
                lo, hi = e.bounds
                assert lo <= e.value <= hi and lo <= e.typical <= hi, e.key
        assert any(e.type == "C" for e in entries), f"{name}: nothing to calibrate"
    assert {e.key for e in base.effect_parameters()} == set(EFFECT_PARAMETERS)
    with pytest.raises(KeyError):
        base.effect_parameters("no_such_effect")


def test_effect_parameter_overrides_round_trip_and_hash(base, tmp_path):
    d = base.with_overrides({"active_valve_lag.tau": 0.003})
    assert d["active_valve_lag.tau"] == 0.003 and base["active_valve_lag.tau"] == 0.005
    assert d.hash() != base.hash()
    with pytest.raises(DesignError, match="outside bounds"):
        base.with_overrides({"active_valve_lag.tau": 1.0})
    again = load(d.dump(tmp_path / "sub" / "d.yaml"), map_dirs=[BASELINE.parent])
    assert again == d and again.hash() == d.hash()
    assert again["active_valve_lag.tau"] == 0.003
    # the piston-leakage gap is a C effect parameter now (conf/lab/sample*.yaml use this key)
    assert base.with_overrides({"piston_leakage.gap": 3e-5})["piston_leakage.gap"] == 3e-5


def _doc():
    return yaml.safe_load(BASELINE.read_text())


def _entry(doc, key):
    return next(e for e in doc["effect_parameters"] if f"{e['effect']}.{e['name']}" == key)


@pytest.mark.parametrize("mutate, message", [
    (lambda d: _entry(d, "active_valve_lag.tau").update(effect="no_such_effect"), "unknown effect 'no_such_effect'"),
    (lambda d: _entry(d, "active_valve_lag.tau").pop("bounds"), "has no bounds"),
    (lambda d: _entry(d, "active_valve_lag.tau").update(value=0.5), "value 0.5 outside bounds"),
    (lambda d: _entry(d, "active_valve_lag.tau").update(colour="red"), "unknown field 'colour'"),
    (lambda d: _entry(d, "aeration.alpha0").update(unit="%"), "expected the SI unit"),
    (lambda d: d["effects"].update(aeration=True) or d["effect_parameters"].remove(_entry(d, "aeration.alpha0")),
     "aeration is on but its parameter"),
    (lambda d: _entry(d, "active_valve_lag.tau").update(effect=[1]), "unknown effect [1]"),
    (lambda d: _entry(d, "active_valve_lag.tau").update(typical=True), "typical True is not a finite number"),
    (lambda d: _entry(d, "active_valve_lag.tau").update(bounds=[1, "a"]), "bounds must be [lower, upper]"),
    (lambda d: _entry(d, "active_valve_lag.tau").update(name="tau_x"), "unknown parameter 'tau_x'"),
    (lambda d: d.update(effect_parameters={"a": 1}), "'effect_parameters' must be a list"),
])
def test_loader_errors_name_file_and_key(tmp_path, mutate, message):
    doc = _doc()
    mutate(doc)
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(doc, sort_keys=False))
    with pytest.raises(DesignError) as ei:
        load(f, map_dirs=[BASELINE.parent])
    text = str(ei.value)
    assert str(f) in text and message in text, text


def test_a_design_without_the_section_still_runs_with_the_effects_off(base, off_runs):
    """Older design files (no effect_parameters) load, pack (effect
    parameters 0) and simulate exactly like the baseline; switching an effect
    on then names the missing parameters."""
    doc = _doc()
    del doc["effect_parameters"]
    d = loads(yaml.safe_dump(doc, sort_keys=False), base_dir=BASELINE.parent)
    assert d.effect_parameters() == []
    assert np.array_equal(_channels(simulate(d, _sine(F13), "module")), off_runs["module"])
    with pytest.raises(ValueError, match="aeration.alpha0"):
        pack(d, effects={"aeration": True})


def test_library_covers_every_switch_and_the_readme_table(base):
    """One record per effect switch; the docs table is the generated one;
    the new effects are off in the baseline and in the lab's nominal copy."""
    assert set(EFFECTS_LIBRARY) == set(EFFECTS) == set(EFFECT_INDEX)
    assert len(NEW) >= 8
    nominal = load(ROOT / "conf" / "lab" / "nominal.yaml")
    for name in NEW:
        assert not base.effects[name] and not nominal.effects[name], name
    assert {e.key for e in nominal.effect_parameters()} == {e.key for e in base.effect_parameters()}
    # the docs page holds the generated table (scripts/mkdocs_hooks.py renders effects_table(baseline))
    page = (ROOT / "docs" / "explanation" / "effects.md").read_text()
    assert "<!-- generated: effects-table -->" in page
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import mkdocs_hooks
    finally:
        sys.path.remove(str(ROOT / "scripts"))
    assert mkdocs_hooks.on_page_markdown(page).count(effects_table(base)) == 1
    for name in NEW:  # each new effect lives in its own submodel file
        assert (ROOT / "src" / "dampertwin" / "model" / f"{name}.py").is_file(), name


# ------------------------------------------------------------ (a) off is off
def _channels(r):
    return np.column_stack([r[k] for k in sorted(r.channels)])


@pytest.fixture(scope="module")
def off_runs(base):
    return {cfg: _channels(simulate(base, _sine(F13), cfg)) for cfg in ("damper", "module")}


@pytest.mark.parametrize("effect", NEW)
def test_off_is_bit_identical_whatever_its_parameters(base, off_runs, effect):
    """Switched off, the effect's parameters (set far from their values) do
    not change a single bit of any output, in the damper and the module."""
    far = base.with_overrides({e.key: _far(e) for e in base.effect_parameters(effect)})
    assert far.hash() != base.hash()
    for cfg, ref in off_runs.items():
        got = _channels(simulate(far, _sine(F13), cfg))
        assert np.array_equal(got, ref, equal_nan=True), (effect, cfg)


def test_off_equals_the_model_without_the_library(base, off_runs):
    """Change detector: the baseline (new effects off) reproduces, bit for
    bit, a short stored run. Stored first from the code before the effect
    library (commit 574b2f9); regenerated by scripts/make_effects_off_reference.py
    when issue 9's sparse LU and libm shortcuts changed the arithmetic (largest
    deviation from the 574b2f9 run: 2.3e-4 of a channel's maximum, the
    friction force; rod force 1.0e-4; rtol is 1e-4), and again for issue 39's third
    speed round (ROS34PW2 in u = Gamma k, reciprocal pivots: largest deviation 5.1e-4 of
    a channel's maximum, the module's friction force; rod force 4.4e-4)."""
    ref = np.load(HEAD_REF)
    for cfg in ("damper", "module"):
        r = simulate(base, _sine(F13), cfg)
        for k in ("rod force [N]", "p compression [Pa]", "p third tube [Pa]", "friction force [N]"):
            assert np.array_equal(r[k], ref[f"{cfg}|{k}"]), (cfg, k)
    assert L.variant(L.CFG_MODULE, pack(base)) == L.CFG_MODULE  # no effect states while they are off


# ------------------------------------------------------------ (b) on moves the KPI
def _last_cycle(r, f):
    return r.time >= r.time[-1] - 1.0 / f


def _phase_lag(r, f):
    """Phase lag [deg] of the rod force's fundamental behind the velocity's (last cycle)."""
    h = _last_cycle(r, f)
    c = np.exp(-2j * np.pi * f * r.time[h])
    d = np.angle(np.sum(r["velocity [m/s]"][h] * c)) - np.angle(np.sum(r["rod force [N]"][h] * c))
    return float(np.degrees((d + np.pi) % (2 * np.pi) - np.pi))


def _kpi(r, f):
    h = _last_cycle(r, f)
    F, mu = r["rod force [N]"][h], r["friction force [N]"][h]
    return dict(F_max=F.max(), F_min=F.min(), phase=_phase_lag(r, f), P_b=r["p third tube [Pa]"][h].max(),
                mu_max=mu.max(), mu_min=mu.min())


def _pair(base, effect, f, cfg="damper", **extra):
    off = simulate(base, _sine(f), cfg)
    on = simulate(_on(base, effect, **extra), _sine(f), cfg)
    assert off.ok and on.ok
    return _kpi(off, f), _kpi(on, f), off, on


def _kpi_leak(base):
    off, on, *_ = _pair(base, "piston_leakage", F13)
    assert on["F_max"] < off["F_max"] - 2.0  # rebound peak lower: the gap bypasses the rebound valve


def _kpi_lag(base):
    off, on, *_ = _pair(base, "active_valve_lag", F16)
    assert on["P_b"] > off["P_b"] * 1.01  # the valve opens late: the third tube pressure overshoots
    assert on["F_min"] < off["F_min"] - 20.0  # ... and the compression peak grows (-51 N at tau = 5 ms)


def _kpi_aeration(base):
    off, on, *_ = _pair(base, "aeration", F16)
    assert on["phase"] > off["phase"] + 1.0  # the air must be compressed first: the force lags more
    assert on["F_min"] > off["F_min"]  # compression peak (negative) lower in magnitude


def _kpi_valve_friction(base):
    off, on, *_ = _pair(base, "valve_friction_current", F13)
    assert on["P_b"] > off["P_b"] * 1.01  # the spool friction holds extra pressure
    assert on["F_min"] < off["F_min"] - 5.0  # compression peak higher in magnitude


def _kpi_thermal(base):
    # the warm-up test (conf/test/thermal.yaml): 10 s at 8 Hz, 20 mm stroke, the smallest heat capacity
    # in bounds (400 J/K): ~8 K warmer; the force moves by well under 1 N (why the workflow needs the
    # thermocouple channel)
    ex = Excitation.sine(0.01, 8.0, 10.0)
    off = simulate(base, ex, "damper", current=1.6, rate=2000.0)
    on = simulate(_on(base, "oil_thermal", **{"oil_thermal.C_th": 400.0}), ex, "damper", current=1.6, rate=2000.0)
    last = off.time > 10.0 - 1.0 / 8.0
    assert on["oil temperature [K]"][-1] > base["oil.T"] + 5.0
    # warmer gas (T/T0) and expanded oil pushed into the reserve: the reserve pressure rises by more than the
    # gas heating alone, and the gas force with it (compression peak larger)
    P_on, P_off = on["p reserve [Pa]"][last].mean(), off["p reserve [Pa]"][last].mean()
    assert P_on / P_off > on["oil temperature [K]"][last].mean() / base["oil.T"]
    assert on["rod force [N]"][last].min() < off["rod force [N]"][last].min() - 1.0


def _kpi_asymmetric(base):
    off, on, *_ = _pair(base, "rod_friction_asymmetric", F13)
    dmu = 0.5 * base["rod_friction_asymmetric.a"] * base["constants.s2"] * 2 * np.pi * F13 * 0.005  # a s2 |v|max / 2
    assert on["mu_max"] > off["mu_max"] + dmu  # rebound film friction (1 + a) s2
    assert on["mu_min"] > off["mu_min"] + dmu  # compression (1 - a) s2, negative: smaller magnitude


def _kpi_seal(base):
    off, on, *_ = _pair(base, "seal_friction_pressure", F13)
    assert on["mu_max"] > off["mu_max"] + 5.0 and on["mu_min"] < off["mu_min"] - 5.0


def _kpi_backlash(base):
    ex = Excitation.sine(duration=0.2, amplitude=0.001, frequency=10.0)
    off = simulate(base, ex, "topmount")
    on = simulate(_on(base, "top_mount_backlash"), ex, "topmount")
    near = np.abs(off["displacement [m]"]) < 2e-4
    F_off, F_on = np.abs(off["top mount force [N]"][near]).max(), np.abs(on["top mount force [N]"][near]).max()
    assert F_on < 0.5 * F_off  # inside the free play the rubber carries (almost) nothing
    assert np.ptp(on["top mount force [N]"]) < np.ptp(off["top mount force [N]"])


def test_free_play_passes_no_rubber_force_out_of_contact(base):
    """Top mount alone, 10 Hz +-1 mm through a +-0.3 mm play: in the middle
    half of the play (|X| < 0.15 mm, out of contact by three roundings) the
    rod feels only the rounding of the dead zone, not the force of the
    rubber's relaxing internal states (27 N before the contact share gated
    it: the play then damped); the cycle still dissipates."""
    ex = Excitation.sine(duration=0.3, amplitude=0.001, frequency=10.0)
    r = simulate(_on(base, "top_mount_backlash"), ex, "topmount", rtol=1e-7)
    X, F, t = r["displacement [m]"], r["top mount force [N]"], r.time
    delta = base["top_mount_backlash.delta"] if "top_mount_backlash.delta" in base.effect_params else 3e-4
    mid = (np.abs(X) < 0.5 * delta) & (t > 0.1)
    assert mid.sum() > 50
    assert np.abs(F[mid]).max() < 5.0, np.abs(F[mid]).max()
    last = t >= 0.2
    assert np.trapezoid(F[last] * np.gradient(X[last], t[last]), t[last]) > 0.0


KPI = {"piston_leakage": _kpi_leak, "active_valve_lag": _kpi_lag, "aeration": _kpi_aeration,
       "valve_friction_current": _kpi_valve_friction, "oil_thermal": _kpi_thermal,
       "rod_friction_asymmetric": _kpi_asymmetric, "seal_friction_pressure": _kpi_seal,
       "top_mount_backlash": _kpi_backlash}


# the candidates of issue 34 (acceptance 3) have their KPI tests in tests/test_effects_candidates.py
KPI_ELSEWHERE = {"fixture_resonance", "active_valve_driver", "gas_release"}


def test_every_new_effect_has_a_kpi_test():
    from test_effects_candidates import KPI as CANDIDATE_KPI
    assert set(CANDIDATE_KPI) == KPI_ELSEWHERE
    assert set(KPI) | KPI_ELSEWHERE == set(NEW) and not set(KPI) & KPI_ELSEWHERE


@pytest.mark.parametrize("effect", sorted(set(NEW) - KPI_ELSEWHERE))
def test_effect_moves_its_kpi(base, effect):
    """Switched on at its typical magnitude, the effect moves the KPI of
    EFFECTS_LIBRARY in the documented direction."""
    KPI[effect](base)


def test_state_effects_run_in_the_extended_configuration(base):
    p = pack(_on(base, "active_valve_lag"))
    assert L.variant(L.CFG_MODULE, p) == L.CFG_MODULE_X
    assert L.variant(L.CFG_MODULE, pack(_on(base, "valve_friction_current"))) == L.CFG_MODULE_X
    # opening lag, spool, oil temperature, free air, load cell (2), coil and eddy currents (2), gas shares (3)
    assert L.N_STATES[L.CFG_MODULE_X] == L.N_STATES[L.CFG_MODULE] + 11
    r = simulate(_on(base, "oil_thermal"), _sine(F13), "module")
    assert r.ok and "top mount force [N]" in r.channels


def test_oil_temperature_output_closes_the_energy_balance(base):
    """oil_thermal: C_th dT + hA int (T - T_amb) dt = int F_d s' dt (the heat the
    damper dissipates, from the rod force and stroke velocity outputs);
    off: the output is the design's oil.T throughout."""
    ex = Excitation.sine(0.01, 8.0, 3.0)
    d = _on(base, "oil_thermal", **{"oil_thermal.hA": 20.0})
    r = simulate(d, ex, "damper", current=1.6, rate=2000.0)
    t, T = r.time, r["oil temperature [K]"]
    P = r["rod force [N]"] * r["velocity [m/s]"]
    work = np.trapezoid(P, t)
    stored = d["oil_thermal.C_th"] * (T[-1] - T[0]) + 20.0 * np.trapezoid(T - d["oil.T"], t)
    assert work > 500.0  # ~300 W over 3 s
    assert stored == pytest.approx(work, rel=2e-3)
    off = simulate(base, ex, "damper", current=1.6, rate=2000.0)
    assert np.all(off["oil temperature [K]"] == base["oil.T"])


# ------------------------------------------------------------ (c) no chattering
@pytest.mark.parametrize("effect, cfg", [("valve_friction_current", "damper"), ("rod_friction_asymmetric", "damper"),
                                         ("seal_friction_pressure", "damper"), ("top_mount_backlash", "module"),
                                         ("active_valve_lag", "damper"), ("aeration", "damper")])
def test_regularised_effects_do_not_chatter(base, effect, cfg):
    """The smoothed switches (named regularisation constants) keep the step
    count and the rejections close to those of the model without them."""
    off = simulate(base, _sine(F13), cfg).stats
    on = simulate(_on(base, effect), _sine(F13), cfg).stats
    assert on.steps <= 1.5 * off.steps + 20, (on, off)
    assert on.rejected <= 0.4 * on.steps, on


def test_backlash_force_does_not_flip_sign_in_a_hold(base):
    """Deflection ramped into the free play and held: the force settles to
    one sign (no chattering across the dead zone)."""
    t = np.linspace(0.0, 0.2, 2001)
    x = np.where(t < 0.05, 2e-4 * t / 0.05, 2e-4)
    ex = Excitation.from_samples(t, x)
    r = simulate(_on(base, "top_mount_backlash"), ex, "topmount")
    F = r["top mount force [N]"][r.time > 0.06]
    assert r.ok and (np.all(F >= 0) or np.all(F <= 0))
    assert r.stats.rejected <= 0.4 * r.stats.steps


def test_regularisation_constants_are_named(base):
    """Every non-smooth term has its named regularisation parameter."""
    for key in ("valve_friction_current.dp_reg", "rod_friction_asymmetric.v_reg", "top_mount_backlash.eps",
                "seal_friction_pressure.p_reg"):
        assert base[key] > 0
    src = (ROOT / "src" / "dampertwin" / "model" / "top_mount_backlash.py").read_text()
    assert re.search(r"sqrt\(u1 \* u1 \+ eps \* eps\)", src)
