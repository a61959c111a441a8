"""New candidates of the effect library (issue 34, acceptance 3):
``fixture_resonance`` (measurement chain: the fixture on the load cell),
``active_valve_driver`` (coil and current driver; invisible at constant
current) and ``gas_release`` (eq. 4.14's gas share as states). Per effect:
off is bit-identical (also beside another effect with states), the KPI of
EFFECTS_LIBRARY moves in its direction at the typical magnitude, and a
physics property that fails if the physics were wrong. The discrepancy
workflow lists them (its catalogue, no workflow run). Short runs."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from scipy import signal
from scipy.integrate import solve_ivp

from dampertwin import simulate
from dampertwin.design import DesignError, loads
from dampertwin.discrepancy.entry import load_config
from dampertwin.discrepancy.refits import calibration_params
from dampertwin.discrepancy.workflow import catalogue
from dampertwin.model import layout as L
from dampertwin.model.active_valve_driver import driver_rates
from dampertwin.model.params import EFFECTS_LIBRARY, effects_table
from dampertwin.truth.params import EFFECTS as TRUTH_EFFECTS

from conftest import BASELINE
from test_effects import ROOT, _channels, _kpi, _on, _sine, base  # noqa: F401 (base: the module-scoped fixture)
from test_effects_chamber import _rhs_at_rest

CANDIDATES = ("fixture_resonance", "active_valve_driver", "gas_release")
F16 = 16.0


def _wide(effect, bounds):
    """The baseline with the C bounds of ``effect``'s parameters widened (limit cases past the design's bounds)."""
    doc = yaml.safe_load(BASELINE.read_text())
    for e in doc["effect_parameters"]:
        if e["effect"] == effect:
            e["type"], e["bounds"] = "C", list(bounds)
    return loads(yaml.safe_dump(doc, sort_keys=False), base_dir=BASELINE.parent)


# ------------------------------------------------------------ library, table, workflow
def test_every_candidate_names_what_it_approximates_in_the_truth(base):
    """Every library candidate (not only the new ones) names the truth mechanism(s) it stands for; the new
    ones name the truth's switch in brackets; the generated table carries the column."""
    for name, r in EFFECTS_LIBRARY.items():
        if not r.thesis:
            assert len(r.truth) > 20, name
    expect = {"fixture_resonance": "fixture", "active_valve_driver": "current_driver", "gas_release": "gas_dissolution"}
    for name, key in expect.items():
        assert key in TRUTH_EFFECTS and f"[{key}]" in EFFECTS_LIBRARY[name].truth, name
    table = effects_table(base)
    assert "| approximates in the truth lab |" in table.splitlines()[0]
    assert all(EFFECTS_LIBRARY[n].truth in table for n in CANDIDATES)
    assert "constant" in EFFECTS_LIBRARY["active_valve_driver"].description  # invisible in the standard tests


def test_the_workflow_lists_the_new_candidates(base):
    """The discrepancy workflow's catalogue (effects off in the design with effect parameters) offers each
    new candidate with its C parameters inside their bounds and a separating test."""
    cfg = load_config(ROOT / "conf")
    cands = {c.name: c for c in catalogue(base, cfg)}
    fitted = {"fixture_resonance": {"fixture_resonance.f_n", "fixture_resonance.zeta"},
              "active_valve_driver": {"active_valve_driver.tau_d", "active_valve_driver.tau_e"},
              "gas_release": {"gas_release.tau_rel"}}
    for name, keys in fitted.items():
        c = cands[name]
        assert c.effects == [name] and {p.key for p in c.params} == keys, name
        assert all(p.lo < c.typical[p.key] < p.hi for p in c.params), name
        assert cfg["separating_tests"][name] in ("random", "monosine", "compliance"), name


def test_an_effect_switched_on_is_calibrated_not_offered(base):
    """Iterated workflow: an effect already on in the design (added in an earlier round) leaves the
    catalogue and its C parameters join the calibration pool, started at the design's values; off, the
    pool is the config's alone."""
    cfg = load_config(ROOT / "conf")
    off = {p.key for p in calibration_params(base, cfg)}
    assert not any(k.startswith(("aeration.", "oil_thermal.")) for k in off)
    on = base.with_overrides({"effects.aeration": True, "effects.oil_thermal": True, "aeration.alpha0": 0.02})
    pool = {p.key: p for p in calibration_params(on, cfg)}
    c_keys = {e.key for n in ("aeration", "oil_thermal") for e in base.effect_parameters(n) if e.type == "C"}
    assert c_keys and set(pool) == off | c_keys  # the C ones only (tau_rel, tau_dis, C_th stay fixed)
    assert pool["aeration.alpha0"].start == 0.02
    assert {"aeration", "oil_thermal"}.isdisjoint(c.name for c in catalogue(on, cfg))


def test_an_effect_that_modifies_an_off_effect_is_refused_and_not_offered(base):
    """seal_friction_pressure and rod_friction_asymmetric change rod friction's LuGre levels, gas_release
    eq. 4.14's gas share: with the effect they modify off they would do nothing. A design switching one on
    without it fails naming both switches; a design with the modified effect off is not offered them."""
    from dampertwin.design.schema import EFFECT_NEEDS

    cfg = load_config(ROOT / "conf")
    assert EFFECT_NEEDS == {"rod_friction_asymmetric": "rod_friction", "seal_friction_pressure": "rod_friction",
                            "gas_release": "gas_content"}
    for eff, need in EFFECT_NEEDS.items():
        with pytest.raises(DesignError, match=rf"effects\.{eff}: true, but it modifies effects\.{need}, which is "
                                              rf"false .*expected effects\.{need}: true"):
            base.with_overrides({f"effects.{eff}": True, f"effects.{need}": False})
        base.with_overrides({f"effects.{eff}": True})  # with the effect it modifies on: a valid design
        offered = {c.name for c in catalogue(base.with_overrides({f"effects.{need}": False}), cfg)}
        assert eff not in offered, eff
        assert eff in {c.name for c in catalogue(base, cfg)}, eff


# ------------------------------------------------------------ off is off, beside another state effect
@pytest.mark.parametrize("effect", CANDIDATES)
def test_off_is_bit_identical_beside_another_state_effect(base, effect):
    """With active_valve_lag on (the extended configuration runs, with this effect's states present), the
    candidate switched off with its parameters far from their values changes not one bit (the plain
    configurations: tests/test_effects.py::test_off_is_bit_identical_whatever_its_parameters)."""
    lag = _on(base, "active_valve_lag")
    far = {e.key: (e.bounds[1] if e.bounds else e.value * 3.0) for e in base.effect_parameters(effect)}
    ref = _channels(simulate(lag, _sine(F16), "damper"))
    got = simulate(lag.with_overrides(far), _sine(F16), "damper", current_before=0.32, current_step_time=0.03)
    assert np.array_equal(_channels(got), ref, equal_nan=True)


# ------------------------------------------------------------ KPI directions
def _band_power(x, fs, lo, hi):
    """Power of x in [lo, hi) Hz (Hann window: the fundamental's leakage stays out of the high bands)."""
    f, P = signal.periodogram(x, fs, window="hann", detrend="linear")
    return float(P[(f >= lo) & (f < hi)].sum())


def _kpi_fixture(base):
    """Load-cell force (damper, 16 Hz): more power near f_n = 700 Hz (valve events ring the fixture: x24),
    less well above it (the mass line: x0.3 over 1-3 kHz), the fundamental unchanged (transmissibility
    1 + O((f / f_n)^2))."""
    off = simulate(base, _sine(F16), "damper")
    on = simulate(_on(base, "fixture_resonance"), _sine(F16), "damper")
    fs = 1.0 / (off.time[1] - off.time[0])
    F_off, F_on = off["rod force [N]"], on["rod force [N]"]
    assert _band_power(F_on, fs, 500.0, 900.0) > 3.0 * _band_power(F_off, fs, 500.0, 900.0)
    assert _band_power(F_on, fs, 1000.0, 3000.0) < 0.7 * _band_power(F_off, fs, 1000.0, 3000.0)
    assert _band_power(F_on, fs, 8.0, 40.0) == pytest.approx(_band_power(F_off, fs, 8.0, 40.0), rel=0.01)


def _kpi_driver(base):
    """A current step 0.32 -> 1.6 A mid-stroke (16 Hz, t = 45 ms): 2 ms after it the third-tube pressure
    is still near the 0.32 A run's, 20 ms after it near the 1.6 A run's (the model without the effect
    follows the command at once)."""
    ex = _sine(F16)
    hi, lo = simulate(base, ex, "damper", current=1.6), simulate(base, ex, "damper", current=0.32)
    on = simulate(_on(base, "active_valve_driver"), ex, "damper", current=1.6, current_before=0.32,
                  current_step_time=0.045)
    t = hi.time
    P = {k: r["p third tube [Pa]"] for k, r in (("hi", hi), ("lo", lo), ("on", on))}
    early = (t >= 0.045) & (t < 0.047)
    assert np.abs(P["on"] - P["lo"])[early].max() < 0.1 * np.abs(P["hi"] - P["lo"])[early].max()
    late = t >= 0.065
    assert np.abs(P["on"] - P["hi"])[late].max() < 0.01 * np.abs(P["hi"] - P["lo"])[late].max()


def _kpi_gas_release(base):
    off, on = simulate(base, _sine(F16), "damper"), simulate(_on(base, "gas_release"), _sine(F16), "damper")
    # the gas does not dissolve within a cycle: the chambers are stiffer, the force lags less (-0.26 deg)
    assert _kpi(on, F16)["phase"] < _kpi(off, F16)["phase"] - 0.1


KPI = {"fixture_resonance": _kpi_fixture, "active_valve_driver": _kpi_driver, "gas_release": _kpi_gas_release}


@pytest.mark.parametrize("effect", CANDIDATES)
def test_candidate_moves_its_kpi(base, effect):
    KPI[effect](base)


# ------------------------------------------------------------ fixture_resonance: the transmissibility
@pytest.mark.parametrize("cfg, channel", [("damper", "rod force [N]"), ("module", "top mount force [N]")])
def test_load_cell_reads_the_force_through_the_base_excited_transmissibility(base, cfg, channel):
    """The load cell's reading is the force without the fixture passed through
    (1 + 2 zeta s/w) / (1 + 2 zeta s/w + s^2/w^2) (an independent linear simulation), starting at rest
    without a transient; the damper itself is unchanged (the stroke, the pressures)."""
    d = _on(base, "fixture_resonance", **{"fixture_resonance.f_n": 400.0, "fixture_resonance.zeta": 0.1})
    off = simulate(base, _sine(F16), cfg, rtol=1e-6)
    on = simulate(d, _sine(F16), cfg, rtol=1e-6)
    w, z = 2 * math.pi * 400.0, 0.1
    F0 = off[channel][0]
    _, want, _ = signal.lsim(([2 * z / w, 1.0], [1 / w ** 2, 2 * z / w, 1.0]), off[channel] - F0, off.time)
    got = on[channel] - F0
    assert np.abs(got - want).max() < 0.01 * np.ptp(off[channel])
    assert np.abs(got - (off[channel] - F0)).max() > 0.02 * np.ptp(off[channel])  # the resonance rings
    assert on[channel][0] == off[channel][0]
    np.testing.assert_allclose(on["p compression [Pa]"], off["p compression [Pa]"], rtol=1e-4)


# ------------------------------------------------------------ active_valve_driver
def test_driver_is_invisible_at_constant_current(base):
    """The standard protocols hold the current: at rest the driver's states do not move (their rates are
    exact zeros), and a mono-sine with the effect on differs from the one without it only by the
    integrator's step choice (its extra states change the error norm: < 1e-4 of the force's range at
    rtol 1e-6, far below the bench's force floor), so the workflow cannot see it there."""
    y, p, dy, _ = _rhs_at_rest(_on(base, "active_valve_driver"))
    o = L.EB_DAMPER + L.EX.i_coil
    assert y[o] == y[o + 1] == p[L.P.CURRENT] and dy[o] == 0.0 and dy[o + 1] == 0.0
    for current in (0.32, 1.6):
        off = simulate(base, _sine(F16), "damper", current=current, rtol=1e-6)["rod force [N]"]
        on = simulate(_on(base, "active_valve_driver"), _sine(F16), "damper", current=current, rtol=1e-6)
        assert np.abs(on["rod force [N]"] - off).max() < 1e-4 * np.ptp(off)


def _driver_run(i0, i1, tau_d, rate, tau_e, t_end):
    sol = solve_ivp(lambda t, x: driver_rates(x[0], x[1], i1, tau_d, rate, tau_e), (0.0, t_end), [i0, i0],
                    rtol=1e-10, atol=1e-12, dense_output=True, method="LSODA")
    return sol.sol


def test_driver_step_response_is_two_lags_or_a_rate_limited_ramp():
    """A small step (far below the rate limit) is the cascade of the two lags,
    I_eff = dI (1 - (tau_d e^(-t/tau_d) - tau_e e^(-t/tau_e)) / (tau_d - tau_e)); a large one ramps the
    coil current at (nearly, tanh) the rate limit, never faster; both settle on the command without
    overshoot."""
    tau_d, tau_e, rate = 1e-3, 2e-3, 600.0
    t = np.linspace(0.0, 0.02, 201)
    s = _driver_run(1.0, 1.001, tau_d, rate, tau_e, 0.02)
    want = 1.0 + 1e-3 * (1.0 - (tau_d * np.exp(-t / tau_d) - tau_e * np.exp(-t / tau_e)) / (tau_d - tau_e))
    np.testing.assert_allclose(s(t)[1], want, rtol=0, atol=1e-8)
    big = _driver_run(0.32, 1.6, tau_d, rate, tau_e, 0.03)
    tt = np.linspace(0.0, 0.03, 3001)
    I = big(tt)
    slope = np.diff(I[0]) / np.diff(tt)
    assert slope.max() <= rate and slope[:3].min() > 0.95 * rate  # the ramp at U / L, not 1.28 A / tau_d
    assert I[1].max() <= 1.6 + 1e-9 and abs(I[1, -1] - 1.6) < 1e-3 and np.all(np.diff(I[1]) >= -1e-12)


# ------------------------------------------------------------ gas_release
def _D(P, theta, p):
    """Eq. 4.15's denominator at pressure P and gas share theta (rho = rho_mix / D), written out here."""
    P_ref = p[L.P.P_REF]
    chi = p[L.P.CHI]
    return ((1 - chi) * math.exp(-(P - P_ref) / p[L.P.K_OIL])
            + theta * chi * p[L.P.TEMP] / p[L.P.T_REF] * (P_ref / P) ** (1 / p[L.P.GAMMA]))


def test_released_gas_conserves_the_chambers_mass(base):
    """At rest (no flow, no stroke; walls rigid) the third tube's gas away from its equilibrium: the gas
    released (theta rising) or dissolving raises or lowers the pressure exactly so that the emulsion's
    density, rho_mix / D(P, theta), and with it the chamber's mass, stays constant."""
    d = _on(base, "gas_release").with_overrides({"effects.wall_compliance": False})
    o = L.EB_DAMPER + L.EX.theta_b
    for shift in (-0.2, 0.2):
        y, p, dy, _ = _rhs_at_rest(d, edit=lambda y, p: y.__setitem__(o, y[o] + shift))
        P, th = y[L.S.P_b], y[o]
        assert (dy[o] > 0) == (shift < 0)  # released below, dissolved above the equilibrium
        h = 1e-6
        dD = (_D(P + h * dy[L.S.P_b], th + h * dy[o], p) - _D(P, th, p)) / h
        terms = abs(_D(P, th + h * dy[o], p) - _D(P, th, p)) / h
        assert dy[L.S.P_b] != 0.0 and abs(dD) < 1e-5 * terms, (dy[L.S.P_b], dD, terms)


def test_gas_release_tends_to_the_thesis_law_as_tau_goes_to_zero(base):
    """tau_rel = tau_dis -> 0 is eq. 4.14-4.16 without delay (the effect off): the rod force's largest
    deviation falls in proportion to tau, to < 1e-4 of its range at 1 us (rtol 1e-7)."""
    wide = _wide("gas_release", (1e-9, 100.0))
    off = simulate(base, _sine(F16), "damper", rtol=1e-7)["rod force [N]"]
    dev = {}
    for tau in (1e-4, 1e-6):
        r = simulate(wide.with_overrides({"effects.gas_release": True, "gas_release.tau_rel": tau,
                                          "gas_release.tau_dis": tau}), _sine(F16), "damper", rtol=1e-7)
        dev[tau] = np.abs(r["rod force [N]"] - off).max() / np.ptp(off)
    assert dev[1e-6] < 1e-4 and dev[1e-6] < 0.05 * dev[1e-4], dev


def test_every_hidden_truth_effect_has_a_documented_family():
    """The discrepancy matrix's expected answer (bench/discrepancy.py, truth lab):
    every hidden effect of the truth is approximated by at least one library
    candidate, and every name a candidate lists is a truth switch or one of the
    truth's always-on mechanisms (truth/solenoid.py, truth/seal.py)."""
    from dampertwin.model.params import EFFECTS_LIBRARY
    from dampertwin.truth.params import EFFECTS, OFF_BY_DEFAULT

    always_on = {"solenoid", "seal"}
    named = {n for r in EFFECTS_LIBRARY.values() for n in r.truth_effects}
    assert named <= set(EFFECTS) | always_on, named - set(EFFECTS) - always_on
    for h in OFF_BY_DEFAULT:
        assert any(h in r.truth_effects for r in EFFECTS_LIBRARY.values()), h
    for r in EFFECTS_LIBRARY.values():  # a new candidate documents what it approximates, both ways
        assert bool(r.truth) == bool(r.truth_effects), r.name


def test_the_matrix_tells_the_truths_always_on_physics_from_foreign_names():
    """bench/discrepancy.py: on the truth lab every case carries the truth's always-on physics (gas
    dissolution, oil heating, the solenoid valve, ...), whose library approximations are off in the
    start design; a control naming aeration + oil_thermal names physics the truth has, a control
    naming piston_leakage (a worn band, hidden only) names physics it has not."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location("bench_discrepancy",
                                                  Path(__file__).resolve().parents[1] / "bench" / "discrepancy.py")
    bd = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bd)
    always = bd.always_on_families("truth")
    assert {"aeration", "gas_release", "oil_thermal", "fixture_resonance"} <= always, always
    assert not {"piston_leakage", "top_mount_backlash"} & always, always  # band / free play: hidden only
    assert bd.always_on_families("library") == set()
    control = {"cell": "control", "truth": [], "verdict": "named", "effects": ["aeration", "oil_thermal"], "group": []}
    assert not bd.foreign(control, "truth", always)
    assert bd.foreign({**control, "effects": ["aeration", "piston_leakage"]}, "truth", always)
    assert not bd.foreign({**control, "verdict": "unexplained", "effects": []}, "truth", always)
    play = {"cell": "single", "truth": ["top_mount_free_play"], "verdict": "named", "group": [],
            "effects": ["aeration", "top_mount_backlash"]}
    assert bd.named_beside(play, "truth") and not bd.foreign(play, "truth", always)
    assert not bd.named_beside({**play, "effects": ["aeration"]}, "truth")
    assert bd.named_beside({**play, "verdict": "ambiguous", "effects": ["aeration"],
                            "group": ["aeration", "top_mount_backlash"]}, "truth")
