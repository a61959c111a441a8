"""The truth's hidden effects in their own physics (issue 34, acceptance 1):
eccentric piston band, two-node thermal network, top-mount free play, air
entrained from the reserve. Each is off unless a sample names it (the
shipped samples' runs are unchanged), obeys its physics (limit cases,
passivity, conservation), and when switched on moves a measured record the
expected way."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from scipy.integrate import solve_ivp

from conftest import ROOT
from dampertwin import cli
from dampertwin.design import load
from dampertwin.excitation import Excitation
from dampertwin.lab import check_sample, load_sample, truth_part
from dampertwin.truth import aeration as ae
from dampertwin.truth import chambers as ch
from dampertwin.truth import freeplay as fp
from dampertwin.truth import params as tp
from dampertwin.truth import thermal as th
from dampertwin.truth.layout import PO
from dampertwin.truth.part import build
from dampertwin.truth.run import extended, simulate

CONF = ROOT / "conf"
NOMINAL = CONF / "lab" / "nominal.yaml"
SAMPLES = (CONF / "lab" / "sample.yaml", CONF / "lab" / "sample2.yaml")
FAST = dict(rate=5000.0, rtol=1e-6, atol=1e-6)


def part(effects=None, values=None):
    nominal = load(NOMINAL)
    p, rest, v = build(nominal, nominal, {"values": values or {}, "effects": effects or {}})
    return p, rest, v


# --- off unless named --------------------------------------------------------------------------------------------

def test_hidden_effects_are_off_unless_a_sample_names_them():
    p, _, _ = part()
    assert p[tp.index("chambers.BAND_ECC")] == 0.0
    for flag in ("thermal.ON", "free_play.ON", "aeration.ON"):
        assert p[tp.index(flag)] == 0.0, flag
    nominal = load(NOMINAL)
    for path in SAMPLES:
        q, _ = truth_part(nominal, nominal, load_sample(path))
        assert not extended(q, "damper") and not extended(q, "module"), path.name
    q, _, _ = part({"top_mount_free_play": True})
    assert not extended(q, "damper") and extended(q, "module")  # the damper test has no top mount
    q, _, _ = part({"band_eccentricity": {"eccentricity": 0.3}})
    assert q[tp.index("chambers.BAND_ECC")] == 0.3 and not extended(q, "damper")


# --- eccentric piston band -------------------------------------------------------------------------------------

def _band(eps, h=3e-5):
    p, _, _ = part()
    p = p.copy()
    o = PO["chambers"]
    p[o + ch.BAND_H], p[o + ch.BAND_ECC] = h, eps
    return p, o


def _gap_profile_integrals(gap, dp, sd, mu, length, n=2001):
    """Per unit circumference of a thin gap ``gap`` (tube wall y = 0 at rest, band y = gap moving at -sd towards
    the compression chamber): the flow through the plane moving with the piston, int (u - V_p) dy, and the
    force on the piston (tension positive): the fluid's shear on the band, minus the ring the chamber pressures
    (taken on the bore area) do not act on as piston face. u(y) from the thin-gap momentum balance
    mu u'' = -dp / length (White, Viscous Fluid Flow, 3-2), integrated by quadrature here."""
    y = np.linspace(0.0, gap, n)
    vp = -sd
    u = dp / (2 * mu * length) * y * (gap - y) + vp * y / gap
    q = np.trapezoid(u - vp, y)
    dudy_band = np.gradient(u, y, edge_order=2)[-1]
    shear_on_band = -mu * dudy_band * length  # traction on the band (fluid below it), per unit circumference
    return q, shear_on_band - dp * gap


@pytest.mark.parametrize("eps", [0.0, 0.3, 0.6, 0.9])
def test_band_flow_and_force_follow_from_the_gap_profile(eps):
    """The closed form equals the quadrature of the gap's velocity profile around the (eccentric) band
    h (1 + eps cos th): flow in the piston's frame, force on the piston beyond P_r A_R - P_c A_B."""
    p, o = _band(eps)
    mu = 0.02
    r, l = 0.5 * p[o + ch.D_PT], p[o + ch.BAND_L]
    th_ = np.linspace(0.0, 2 * np.pi, 721)
    gaps = p[o + ch.BAND_H] * (1 + eps * np.cos(th_))
    for dp, sd in ((2e6, 0.4), (2e6, -0.4), (0.0, 0.5), (-3e5, 1.2)):
        Q, F, L = ch.band_leakage(dp, sd, mu, p, o)
        loc = np.array([_gap_profile_integrals(g, dp, sd, mu, l) for g in gaps])
        assert Q == pytest.approx(np.trapezoid(loc[:, 0], th_) * r, rel=1e-4, abs=1e-12)
        assert F == pytest.approx(np.trapezoid(loc[:, 1], th_) * r, rel=1e-4, abs=1e-6)
        assert L == pytest.approx(dp * Q + F * sd, rel=1e-12)
    p0, _ = _band(0.0)
    Qp0 = ch.band_leakage(2e6, 0.0, mu, p0, o)[0]
    assert ch.band_leakage(2e6, 0.0, mu, p, o)[0] / Qp0 == pytest.approx(1 + 1.5 * eps ** 2, rel=1e-12)


def test_a_piston_squeezing_its_chamber_pushes_half_the_ring_out():
    """No pressure difference, the piston moving into the rebound chamber: the oil of the band's ring is half
    carried along, half left behind, so the squeezed (bore-sized) rebound chamber loses c h sd / 2 > 0 to the
    compression chamber, and the band only drags (no pressure force)."""
    p, o = _band(0.0)
    c, h, sd = math.pi * p[o + ch.D_PT], p[o + ch.BAND_H], 0.5
    Q, F, L = ch.band_leakage(0.0, sd, 0.02, p, o)
    assert Q == pytest.approx(0.5 * c * h * sd, rel=1e-12) and Q > 0
    assert F == pytest.approx(c * 0.02 * p[o + ch.BAND_L] * sd / h, rel=1e-12) and L > 0


def test_eccentric_band_dissipates_and_thins_with_temperature():
    """The band's power dp Q + F sd >= 0 at any pressure drop and rate
    (viscous flow is passive), and a warmer oil (lower viscosity) leaks more."""
    p, o = _band(0.8)
    rng = np.random.default_rng(4)
    for dp, sd in zip(rng.normal(0, 3e6, 200), rng.normal(0, 1.0, 200)):
        assert ch.band_leakage(dp, sd, 0.02, p, o)[2] >= 0.0
    from dampertwin.truth.fluid import viscosity

    oo = PO["oil"]
    mu = [viscosity(T, p, oo) * p[oo] for T in (300.0, 330.0)]
    assert ch.band_leakage(1e6, 0.0, mu[1], p, o)[0] > 1.5 * ch.band_leakage(1e6, 0.0, mu[0], p, o)[0]


def _damper(effects, values=None, T=1.0, f=3.0, amp=0.02, current=0.9):
    p, rest, _ = part(effects, values)
    return simulate(p, Excitation.sine(amp, f, T, ramp=0.1), "damper", current=current, rest=rest, **FAST)


def test_an_eccentric_worn_band_leaks_more_and_takes_rebound_force():
    worn = {"chambers.BAND_H": 5e-5}
    off = _damper({}, worn)
    on = _damper({"band_eccentricity": {"eccentricity": 0.9}}, worn)
    assert off.ok and on.ok
    last = off.time > off.time[-1] - 1 / 3
    assert on["rod force [N]"][last].max() < off["rod force [N]"][last].max() - 5.0  # N
    assert np.abs(on["flow piston [m^3/s]"][last]).max() > np.abs(off["flow piston [m^3/s]"][last]).max()


# --- two-node thermal network ----------------------------------------------------------------------------------

def _thermal(G_OW, C_OIL=570.0, C_W=630.0):
    q = np.zeros(len(th.PARAMS))
    q[th.C_OIL], q[th.C_W], q[th.G_OW], q[th.ON] = C_OIL, C_W, G_OW, 1.0
    return q


def _heat(q, P, HA, t_end, T0=300.0):
    def f(t, z):
        return th.two_node(z[0], z[1], P, HA, T0, q, 0)
    return solve_ivp(f, (0.0, t_end), [T0, T0], method="Radau", rtol=1e-10, atol=1e-10, dense_output=True)


def test_two_nodes_with_an_infinite_conductance_are_one_node():
    """G_OW -> inf: the oil follows the one-node law C dT/dt = P - HA (T -
    T_amb) with C = C_OIL + C_W, T = T_amb + P / HA (1 - exp(-HA t / C));
    a finite G_OW heats the oil faster at first (its node is smaller)."""
    from dampertwin.truth.params import TRUTH_NOMINAL as N

    # the limit is the truth's own one-node law: the two capacities sum to its C_TH
    assert N["thermal.C_OIL"] + N["thermal.C_W"] == N["chambers.C_TH"]
    assert (N["thermal.C_OIL"], N["thermal.C_W"]) == (570.0, 630.0)
    P, HA = 200.0, 5.0
    t = np.linspace(0.0, 600.0, 13)
    one = 300.0 + P / HA * (1 - np.exp(-HA * t / (570.0 + 630.0)))
    r = _heat(_thermal(1e7), P, HA, 600.0)
    assert np.max(np.abs(r.sol(t)[0] - one)) < 1e-3
    r = _heat(_thermal(10.0), P, HA, 600.0)
    assert r.sol(30.0)[0] > 300.0 + P / HA * (1 - math.exp(-HA * 30.0 / (570.0 + 630.0))) + 1.0


def test_two_node_network_balances_power_and_reaches_the_series_conductance():
    """Energy: C_OIL dT_oil + C_W dT_w = P - HA (T_w - T_amb) at any state;
    steady state: T_oil - T_amb = P (1/G_OW + 1/HA) (conductances in series)."""
    q = _thermal(10.0)
    rng = np.random.default_rng(5)
    for T, Tw, P in zip(rng.uniform(290, 360, 20), rng.uniform(290, 360, 20), rng.uniform(0, 500, 20)):
        a, b = th.two_node(T, Tw, P, 5.0, 300.0, q, 0)
        assert 570.0 * a + 630.0 * b == pytest.approx(P - 5.0 * (Tw - 300.0), rel=1e-12, abs=1e-9)
    r = _heat(q, 100.0, 5.0, 5e4)
    assert r.y[0, -1] - 300.0 == pytest.approx(100.0 * (1 / 10.0 + 1 / 5.0), rel=1e-4)


def test_two_node_thermal_heats_the_measured_oil_faster():
    off = _damper({})
    on = _damper({"two_node_thermal": True})
    rise = lambda r: r["oil temperature [K]"][-1] - r["oil temperature [K]"][0]  # noqa: E731
    assert off.ok and on.ok and rise(off) > 0.05
    assert rise(on) > 1.5 * rise(off)  # 570 J/K of oil, not 1200 J/K of oil and steel


# --- top-mount free play ---------------------------------------------------------------------------------------

def _play(gap=1e-4):
    p, _, _ = part({"top_mount_free_play": {"clearance": gap}})
    return p, PO["free_play"]


def test_free_play_contact_is_zero_inside_never_pulls_and_dissipates():
    p, o = _play()
    gap, eps, k = p[o + fp.GAP], p[o + fp.EPS], p[o + fp.K]
    inner = gap - 800 * eps  # the penetration's rounding underflows to exactly 0 (exp(-800) = 0)
    assert inner > 0.9 * gap
    for x in np.linspace(-inner, inner, 41):
        for v in (-1.0, 0.0, 1.0):
            assert fp.contact(x, v, p, o) == (0.0, 0.0)
        assert abs(fp.contact(np.sign(x) * gap, 0.0, p, o)[0]) <= k * eps ** 1.5  # at the edge: the rounding only
    rng = np.random.default_rng(6)
    for x, v in zip(rng.uniform(-3 * gap, 3 * gap, 400), rng.normal(0, 2.0, 400)):
        F, loss = fp.contact(x, v, p, o)
        assert F * np.sign(x) >= 0.0  # pushes the rod back towards the sleeve's middle, never pulls it out
        assert loss >= -1e-9 * abs(F * v)
    # power: F v = dE/dt + loss, E = int K d^1.5 d(delta) per side (d the rounded penetration, fluid.ramp)
    from dampertwin.truth.fluid import ramp

    for x, v in zip(rng.uniform(-3 * gap, 3 * gap, 200), rng.normal(0, 2.0, 200)):
        F, loss = fp.contact(x, v, p, o)
        stored_rate = sum(k * ramp(s * x - gap, eps) ** 1.5 * s * v for s in (1, -1))
        assert F * v == pytest.approx(stored_rate + loss, rel=1e-9, abs=1e-12)
    # Hunt-Crossley: loading (penetration growing) takes more force than unloading at the same penetration
    up, _ = fp.contact(1.2 * gap, 0.5, p, o)
    down, _ = fp.contact(1.2 * gap, -0.5, p, o)
    assert up > down > 0.0
    assert fp.contact(1.2 * gap, 0.0, p, o)[0] == pytest.approx(p[o + fp.K] * (0.2 * gap) ** 1.5, rel=1e-6)


def test_zero_clearance_has_no_dead_zone():
    p, o = _play(0.0)
    for x in (1e-7, 1e-6, 1e-5):
        assert fp.contact(x, 0.0, p, o)[0] > 0.0 and fp.contact(-x, 0.0, p, o)[0] < 0.0


def _module(effects, T=0.3):
    p, rest, _ = part(effects)
    return simulate(p, Excitation.sine(0.003, 15.0, T, ramp=0.05), "module", current=0.9, rest=rest, **FAST)


def test_free_play_knocks_on_the_measured_rod_acceleration():
    """With +-0.1 mm of play the rod hits the sleeve at each reversal: the
    rod acceleration's peaks grow by an order of magnitude; with zero
    clearance they stay near the mount without play."""
    off = _module({})
    on = _module({"top_mount_free_play": True})
    tight = _module({"top_mount_free_play": {"clearance": 0.0}})
    assert off.ok and on.ok and tight.ok
    peak = lambda r: np.abs(r["rod acceleration [m/s^2]"][r.time > 0.1]).max()  # noqa: E731
    assert peak(on) > 10 * peak(off)
    assert peak(tight) < 2 * peak(off)


# --- air entrained at low reserve pressure -----------------------------------------------------------------------

def test_entrainment_starts_below_its_onset_pressure_and_only_on_intake():
    p, _, _ = part({"air_entrainment": True})
    o = PO["aeration"]
    P_E, phi = p[o + ae.P_E], p[o + ae.PHI_E]
    assert ae.entrainment(0.0, 1e-4, 1.01 * P_E, 1e5, p, o) == (0.0, 0.0)
    assert ae.entrainment(0.0, -1e-4, 0.5 * P_E, 1e5, p, o)[0] == 0.0
    e_in, _ = ae.entrainment(0.0, 1e-4, 0.5 * P_E, 1e5, p, o)
    assert e_in == pytest.approx(0.5 * phi * 1e-4 * 0.5 * P_E / 1e5, rel=1e-12)
    assert ae.entrainment(2e-6, 0.0, P_E, 1e5, p, o)[1] == pytest.approx(2e-6 / p[o + ae.TAU_E])


def test_entrained_gas_moves_from_the_reserve_it_is_not_created():
    """At a state with the base intake open and the reserve below the
    onset, the reserve gas loses exactly the mass the compression chamber's
    entrained gas gains (gas dissolution off: no other gas exchange)."""
    from dampertwin.truth import gas as gs
    from dampertwin.truth import intake as ik
    from dampertwin.truth.fluid import P_REF
    from dampertwin.truth.damper import rhs_damper_ext
    from dampertwin.truth.layout import CURRENT, E_GE, EX_DT, EX_T0, EXT_AT, N_OUT, SO, state_names
    from dampertwin.truth.run import _extend, _rest_damper

    p, rest, _ = part({"air_entrainment": {"onset_pressure": 6e5}, "gas_dissolution": False})
    ex = Excitation.sine(0.01, 2.0, 0.5)
    p[PO["run"] + CURRENT] = 0.9
    p[PO["run"] + EX_T0], p[PO["run"] + EX_DT] = ex.t0, ex.dt
    p[PO["chambers"] + ch.T_AMB] = rest["T"]
    y = _extend(_rest_damper(p, "damper", 0.0, rest["T"], rest["P0"], rest["V_gas0"]), p, "damper", rest["T"],
                rest["P0"])
    y[SO["chambers"] + ch.PC] = 1.5e5  # the compression chamber sucks through the open base intake
    y[SO["base_intake"] + ik.X] = 3e-4
    e = EXT_AT["damper+"]
    y[e + E_GE] = 3e-7
    dy, out = np.zeros(len(state_names("damper+"))), np.zeros(N_OUT)
    rhs_damper_ext(0.0, y, p, ex.array(), np.zeros(1), dy, out)
    P_ref = p[PO["oil"] + P_REF]
    m_rate = dy[e + E_GE] * P_ref / (p[PO["gas"] + gs.R_S] * rest["T"])
    assert dy[e + E_GE] > 0.0  # entrainment outweighs release here
    assert dy[SO["gas"] + gs.M_G] == pytest.approx(-m_rate, rel=1e-12)


def test_entrained_air_softens_the_measured_compression_force():
    """Low reserve pressure (onset above the precharge): gas drawn in on
    each rebound stroke sits in the compression chamber, so after the
    reversal into compression the force builds later: on the accelerating
    compression branch the force is smaller; oil mass stays conserved."""
    off = _damper({})
    on = _damper({"air_entrainment": {"onset_pressure": 6e5, "fraction": 0.2}})
    assert off.ok and on.ok
    assert np.ptp(on["oil mass [kg]"]) / on["oil mass [kg]"][0] < 1e-7

    def early_compression(r):
        last = r.time > r.time[-1] - 1 / 3
        v, F = r["velocity [m/s]"][last], r["rod force [N]"][last]
        acc = np.gradient(v) < 0  # compression speed (v < 0) growing
        return np.mean(np.abs(F[(v < -0.05) & acc]))

    assert early_compression(on) < 0.9 * early_compression(off)


# --- energy: every new loss is counted ------------------------------------------------------------------------

@pytest.mark.parametrize("configuration, effects, amp, freq", [
    ("damper", {"band_eccentricity": {"eccentricity": 0.8}, "two_node_thermal": True,
                "air_entrainment": {"onset_pressure": 6e5, "fraction": 0.2}}, 0.015, 4.0),
    ("module", {"top_mount_free_play": True, "payne": False}, 0.004, 10.0),
])
def test_the_actuators_work_per_cycle_is_what_the_effects_dissipate(configuration, effects, amp, freq):
    """As tests/test_truth_physics.py's cycle, with the hidden effects on:
    the actuator's work over the last cycle equals the dissipated power's
    integral (band, contacts, ...) minus the solenoid's work within 1 %
    (gas dissolution off: its drift is not a cycle's)."""
    p, rest, _ = part({**effects, "gas_dissolution": False}, {"chambers.BAND_H": 3e-5})
    T = 3.0 / freq
    r = simulate(p, Excitation.sine(amp, freq, T, ramp=1.0 / freq), configuration, current=1.2, rest=rest,
                 rate=20_000.0)
    assert r.ok
    last = r.time >= r.time[-1] - 1.0 / freq
    work = np.trapezoid(r["actuator force [N]"][last], r["displacement [m]"][last])
    diss = np.trapezoid(r["dissipated power [W]"][last] - r["magnetic power [W]"][last], r.time[last])
    assert work > 5.0
    assert abs(work - diss) / work < 0.01, (work, diss)


# --- the sample schema ---------------------------------------------------------------------------------------------

def _sample(tmp_path, effects):
    doc = yaml.safe_load(SAMPLES[0].read_text())
    doc["truth"]["effects"].update(effects)
    p = tmp_path / "hidden_effects_sample.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def test_a_sample_configures_hidden_effects_under_effects(tmp_path):
    path = _sample(tmp_path, {"band_eccentricity": {"eccentricity": 0.4}, "two_node_thermal": True,
                              "top_mount_free_play": {"clearance": 2e-4, "stiffness": 1e10},
                              "air_entrainment": False})
    s = load_sample(path)
    nominal = load(NOMINAL)
    check_sample(s, nominal)
    p, _ = truth_part(nominal, nominal, s)
    assert p[tp.index("chambers.BAND_ECC")] == 0.4 and p[tp.index("thermal.ON")] == 1.0
    assert p[tp.index("free_play.GAP")] == 2e-4 and p[tp.index("free_play.K")] == 1e10
    assert p[tp.index("aeration.ON")] == 0.0


@pytest.mark.parametrize("effects, key", [
    ({"top_mount_free_play": {"gap": 1e-4}}, "truth.effects.top_mount_free_play.gap"),
    ({"band_eccentricity": {"eccentricity": 1.2}}, "truth.effects.band_eccentricity.eccentricity"),
    ({"air_entrainment": {"fraction": "lots"}}, "truth.effects.air_entrainment.fraction"),
    ({"payne": {"amplitude": 1.0}}, "truth.effects.payne"),
    ({"two_node_thermal": 1}, "truth.effects.two_node_thermal"),
])
def test_bad_hidden_effect_settings_exit_2_naming_file_and_key(tmp_path, capsys, effects, key):
    path = _sample(tmp_path, effects)
    rc = cli.main(["lab", "--sample", str(path), "--out", str(tmp_path / "out"), "--tests", "monosine"])
    err = capsys.readouterr().err
    assert rc == 2 and str(path) in err and key in err, err
    assert not (tmp_path / "out").exists()


def test_a_bench_case_hides_a_truth_effect_in_a_lab3_sample(tmp_path):
    """discrepancy.hidden.hidden_sample on a lab-3 base writes the effect
    under truth.effects: the sample loads, the part is the nominal truth
    (the base's deviations dropped) with the effect on at the given value."""
    from dampertwin.discrepancy.hidden import hidden_sample

    base = {k: v for k, v in load_sample(SAMPLES[0]).items() if not k.startswith("_")}
    s = hidden_sample(base, effects={"top_mount_free_play": {"clearance": 1.5e-4}}, values={"chambers.BAND_H": 2e-5})
    assert s["truth"]["effects"] == {"top_mount_free_play": {"clearance": 1.5e-4}}
    assert s["truth"]["values"] == {"chambers.BAND_H": 2e-5} and base["truth"]["values"]  # the base untouched
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(s))
    nominal = load(NOMINAL)
    p, _ = truth_part(nominal, nominal, load_sample(path))
    assert p[tp.index("free_play.ON")] == 1.0 and p[tp.index("free_play.GAP")] == 1.5e-4
    kept = hidden_sample(base, effects={"air_entrainment": True}, keep_deviations=True)
    assert kept["truth"]["values"] == base["truth"]["values"] and kept["truth"]["effects"]["air_entrainment"] is True
    with pytest.raises(ValueError, match="factors"):
        hidden_sample(base, factors={"oil.nu": 1.1})
