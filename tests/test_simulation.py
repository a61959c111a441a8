"""Assembled model through the compiled solver: physics properties that
would fail if the model were wrong."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dampertwin import Excitation, simulate, simulate_batch
from dampertwin.design import load
from dampertwin.reference import simulate_reference

from conftest import BASELINE

F13 = 13.0
MONO = dict(amplitude=0.005, frequency=F13)  # 10 mm stroke (THESIS-ERRATA 36)


@pytest.fixture(scope="module")
def base():
    return load(BASELINE)


def last_cycle(r, f):
    return r.time >= r.time[-1] - 1.0 / f - 1e-12


def test_no_motion_keeps_rest_state(base):
    ex = Excitation.sine(0.0, F13, 0.1)
    r = simulate(base, ex, "module")
    P0 = base["oil.P_0"]
    for c in ("p rebound [Pa]", "p compression [Pa]", "p third tube [Pa]", "p reserve [Pa]"):
        assert np.max(np.abs(r[c] - P0)) < 1e-6 * P0, c
    A_rod = math.pi * base["geometry.D_R"] ** 2 / 4
    gas_force = -(P0 - base["constants.P_atm"]) * A_rod  # the only force at rest: gas pushes the rod out
    assert np.max(np.abs(r["rod force [N]"] - gas_force)) < 1e-6 * abs(gas_force)
    assert np.max(np.abs(r["top mount force [N]"] - gas_force)) < 1e-6 * abs(gas_force)
    assert np.max(np.abs(r["rod acceleration [m/s^2]"])) < 1e-6
    assert np.max(np.abs(r["friction force [N]"])) < 1e-9
    for k in ("piston_rebound", "piston_intake", "base_compression", "base_intake"):
        assert np.all(r[f"lift {k} [m]"] <= 0.0)  # seated
    assert r.stats.steps < 200


def test_volume_balance_closes(base):
    """Gas volume change (from the reserve pressure via the gas law) equals the
    chamber volume change plus the compliance storage of the three chambers,
    integrated over a mono-sine: flows go where they should."""
    ex = Excitation.sine(duration=2.0 / F13, **MONO)
    r = simulate(base, ex, "module", rate=100e3)
    G = base["oil.Gamma"]
    Vg = base["constants.V_gas0"] * (base["oil.P_0"] / r["p reserve [Pa]"]) ** (1 / G)
    D_R = base["geometry.D_R"]
    A_rod = math.pi * D_R**2 / 4
    s = r["stroke [m]"]
    storage = r["storage rebound [m^3/s]"] + r["storage compression [m^3/s]"] + r["storage third tube [m^3/s]"]
    from scipy.integrate import cumulative_trapezoid

    lhs = Vg - Vg[0]
    rhs = A_rod * (s - s[0]) + cumulative_trapezoid(storage, r.time, initial=0.0)
    scale = np.max(np.abs(lhs))
    assert scale > 1e-7  # the rod really moved oil
    assert np.max(np.abs(lhs - rhs)) < 1e-3 * scale


@pytest.mark.parametrize("configuration", ["damper", "module"])
def test_energy_dissipated_per_cycle(base, configuration):
    ex = Excitation.sine(duration=3.0 / F13, **MONO)
    r = simulate(base, ex, configuration)
    m = last_cycle(r, F13)
    work = np.trapezoid(r["rod force [N]"][m], r["displacement [m]"][m])
    assert work > 0.5  # J per cycle; the damper absorbs energy


def test_energy_dissipated_on_flow_bench(base):
    Q = 30 / 60000  # 30 l/min peak
    ex = Excitation.sine(Q / 2, 2.0, 1.5, ramp=0.0)
    ex = Excitation(ex.t0, ex.dt, ex.value + Q / 2, ex.rate, "flow")  # 0 .. Q, one direction
    r = simulate(base, ex, "valve", bench_valve="piston_rebound")
    m = r.time >= 1.0
    power = r["dp [Pa]"][m] * r["valve flow [m^3/s]"][m]
    assert np.trapezoid(power, r.time[m]) > 0


@pytest.fixture(scope="module")
def curving_05(base):
    """Curving test at 0.5 m/s: 50 mm stroke, peak velocity 0.5 m/s."""
    A = 0.025
    f = 0.5 / (2 * math.pi * A)
    ex = Excitation.sine(A, f, 2.0 / f)
    peaks = {}
    for I in (0.32, 0.9, 1.6):
        r = simulate(base, ex, "damper", current=I)
        m = last_cycle(r, f)
        F = r["rod force [N]"][m]
        peaks[I] = (F.max(), F.min())
    return peaks


def test_higher_current_higher_force_both_directions(curving_05):
    reb = [curving_05[I][0] for I in (0.32, 0.9, 1.6)]
    comp = [curving_05[I][1] for I in (0.32, 0.9, 1.6)]
    assert reb[0] < reb[1] < reb[2], reb
    assert comp[0] > comp[1] > comp[2], comp
    assert reb[0] > 0 > comp[0]


def _kpis(r, f):
    m = last_cycle(r, f)
    return np.array([r["rod force [N]"][m].max(), r["rod force [N]"][m].min(),
                     r["rod acceleration [m/s^2]"][m].max(), r["rod acceleration [m/s^2]"][m].min()])


def test_halving_tolerance_changes_kpis_little(base):
    ex = Excitation.sine(duration=3.0 / F13, **MONO)
    k1 = _kpis(simulate(base, ex, "module"), F13)
    k2 = _kpis(simulate(base, ex, "module", rtol=0.5e-4), F13)
    assert np.max(np.abs(k1 - k2) / np.abs(k2)) < 0.005


def test_seated_valve_does_not_chatter(base):
    """A shim valve held shut by its preload, fed a constant bleed flow: after
    the start the integrator takes few steps and the lift stays still."""
    ex = Excitation.constant_rate(0.5 / 60000, 1.0, kind="flow")  # 0.5 l/min
    r = simulate(base, ex, "valve", bench_valve="piston_rebound", h_max=0.05)
    x = r["lift [m]"]
    assert np.all(x < 0)
    late = r.time > 0.5
    assert np.ptp(x[late]) < 1e-10
    assert r.stats.steps < 300, r.stats  # a chattering valve needs thousands


def test_compiled_matches_reference_path(base):
    """The compiled Rodas4 run and scipy BDF on plain-Python equations agree
    within 1 % of the peak on a 0.2 s mono-sine window."""
    ex = Excitation.sine(duration=0.2, **MONO)
    r = simulate(base, ex, "module")
    ref = simulate_reference(base, ex, "module", rtol=1e-6)
    for c in ("rod force [N]", "rod acceleration [m/s^2]"):
        a, b = r[c], ref[c]
        assert abs(a.max() - b.max()) < 0.01 * np.max(np.abs(b)), c
        assert abs(a.min() - b.min()) < 0.01 * np.max(np.abs(b)), c
        assert np.max(np.abs(a - b)) < 0.02 * np.max(np.abs(b)), c


def test_intake_openings_make_the_largest_rod_acceleration_peaks(base):
    """Thesis 6.5.1: in the 13 Hz mono-sine at 1.6 A the largest rod
    acceleration peaks coincide with the intake-valve openings (base intake in
    rebound, piston intake in compression): the peak falls within 2 ms
    (9 deg of the cycle) after the intake valve lifts off its seat."""
    ex = Excitation.sine(duration=4.0 / F13, **MONO)
    r = simulate(base, ex, "module", current=1.6, rate=50e3)
    m = last_cycle(r, F13)
    t, a, v = r.time[m], r["rod acceleration [m/s^2]"][m], r["velocity [m/s]"][m]
    for stroke, valve in ((v > 0, "base_intake"), (v < 0, "piston_intake")):
        i_peak = np.argmax(np.where(stroke, np.abs(a), 0.0))
        x = r[f"lift {valve} [m]"][m]
        opens = t[1:][(x[1:] > 0) & (x[:-1] <= 0)]
        assert len(opens), valve
        lag = t[i_peak] - opens
        assert np.any((lag >= 0) & (lag <= 2e-3)), (valve, t[i_peak], opens)


# ------------------------------------------------------------ effect switches
EFFECT_PROBES = {
    "gas_content": {"oil.chi": 0.02},
    "wall_compliance": {"third_tube.E": 2e10},
    "valve_stiction": {"piston_intake.x_v0": 8e-6, "base_intake.x_v0": 8e-6},
    "shim_friction": {"piston_rebound.F_c": 60.0, "base_compression.F_c": 60.0},
    "jet_force": {"constants.zeta": 0.3},
    "flow_number_cq": {"piston_rebound.lambda_crit": 5000.0, "base_compression.lambda_crit": 5000.0},
    "slot_restriction": {"piston_rebound.A_slot": 1e-5, "base_compression.A_slot": 1e-5},
    "rod_friction": {"rod_friction.F_c": 150.0, "rod_friction.F_s": 200.0},
    "top_mount_dynamics": {"top_mount.k1": 8e6, "top_mount.c0": 2000.0},
    "piston_leakage": {"piston_leakage.gap": 6e-5},
}


@pytest.fixture(scope="module")
def mono_short():
    return Excitation.sine(duration=2.0 / F13, **MONO)


def _run(design, ex, **effects):
    r = simulate(design, ex, "module", effects=effects or None)
    assert r.ok
    return np.column_stack([r["rod force [N]"], r["rod acceleration [m/s^2]"], r["p compression [Pa]"]])


@pytest.mark.parametrize("effect", sorted(EFFECT_PROBES))
def test_effect_switch(base, mono_short, effect):
    """On: the effect's parameters change the outputs and switching it off
    changes them. Off: the outputs do not depend on the effect's parameters
    at all (bit for bit), i.e. they are exactly those of a model without it."""
    probe = base.with_overrides(EFFECT_PROBES[effect])
    on = _run(base, mono_short, **{effect: True})
    on_probe = _run(probe, mono_short, **{effect: True})
    off = _run(base, mono_short, **{effect: False})
    off_probe = _run(probe, mono_short, **{effect: False})
    assert not np.allclose(on, on_probe, rtol=1e-4, atol=0), "parameters of an active effect must matter"
    assert not np.array_equal(on, off), "switching the effect off must change the outputs"
    assert np.array_equal(off, off_probe), "a switched-off effect must leave no trace"


def test_cavitation_switch(base):
    """Cavitation floor: with a vapour pressure inside the working range the
    compression chamber is held near P_vap when on; off, P_vap is unused
    (gas content off, since eq. 4.14 also uses P_vap)."""
    ex = Excitation.sine(0.025, 0.5 / (2 * math.pi * 0.025), 0.2)
    pv = 3.6e5
    probe = base.with_overrides({"oil.P_vap": pv})
    off = simulate(base, ex, "damper", effects={"cavitation": False, "gas_content": False})
    off_p = simulate(probe, ex, "damper", effects={"cavitation": False, "gas_content": False})
    on_p = simulate(probe, ex, "damper", effects={"cavitation": True, "gas_content": False})
    assert np.array_equal(off["rod force [N]"], off_p["rod force [N]"])
    assert off_p["p compression [Pa]"].min() < pv - 0.2e5  # would cavitate
    assert on_p["p compression [Pa]"].min() > pv - 0.1e5
    assert on_p["p compression [Pa]"].min() > off_p["p compression [Pa]"].min()


# ------------------------------------------------------------ API
def test_result_frame_and_batch(base, mono_short):
    r = simulate(base, mono_short, "module")
    df = r.to_frame()
    assert {"time [s]", "rod force [N]", "top mount force [N]", "rod acceleration [m/s^2]",
            "lift base_intake [m]", "flow active valve [m^3/s]"} <= set(df.columns)
    assert df.attrs["design_hash"] == base.hash()
    assert np.all(np.diff(df["time [s]"]) > 0)
    variants = [base, base.with_overrides({"piston_rebound.a": 400.0})]
    t, ch, status = simulate_batch(variants, mono_short, "module", channels=["rod force [N]"])
    assert list(status) == [0, 0]
    np.testing.assert_array_equal(ch["rod force [N]"][0], r["rod force [N]"])  # same code path
    assert not np.array_equal(ch["rod force [N]"][1], ch["rod force [N]"][0])


def test_bad_configuration_and_excitation_rejected(base, mono_short):
    with pytest.raises(ValueError, match="configuration"):
        simulate(base, mono_short, "car")
    with pytest.raises(ValueError, match="flow excitation"):
        simulate(base, mono_short, "valve", bench_valve="piston_rebound")
    with pytest.raises(ValueError, match="bench_valve"):
        simulate(base, Excitation.constant_rate(1e-4, 0.1, kind="flow"), "valve")


def test_default_integrator_follows_the_tolerance(base):
    """``method=None`` is ROS34PW2 at the fits' tolerance and Rodas4 at tight
    ones (the lab's truth); simulate and simulate_batch both follow it, and
    the two methods agree on the mono-sine force within their tolerance."""
    from dampertwin.simulation import TIGHT_RTOL, default_method

    assert default_method(1e-4) == "ros34pw2" and default_method(1e-3) == "ros34pw2"
    assert default_method(TIGHT_RTOL) == "rodas4" and default_method(1e-8) == "rodas4"
    ex = Excitation.sine(0.005, 13.0, 2 / 13.0)
    default = simulate(base, ex, "module")
    w = simulate(base, ex, "module", method="ros34pw2")
    assert np.array_equal(default["rod force [N]"], w["rod force [N]"])
    _, batch, status = simulate_batch([base], ex, "module", channels=["rod force [N]"])
    assert status[0] == 0 and np.array_equal(batch["rod force [N]"][0], w["rod force [N]"])
    tight_default = simulate(base, ex, "module", rtol=1e-6)
    tight_rodas = simulate(base, ex, "module", rtol=1e-6, method="rodas4")
    assert np.array_equal(tight_default["rod force [N]"], tight_rodas["rod force [N]"])
    assert tight_default.stats.jacobians == tight_default.stats.accepted  # Rodas4: a Jacobian every step
    F, Ft = w["rod force [N]"], tight_rodas["rod force [N]"]
    assert np.max(np.abs(F - Ft)) < 2e-3 * np.max(np.abs(Ft))
