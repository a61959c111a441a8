"""Physics checks of the lab's truth (issue 32, acceptance 3): oil mass
conservation, the energy balance of a cycle, the static equilibrium on the
gas precharge, and each subsystem against an analytic or literature case
(annular plate deflection, R-L step, polytropic limits of the gas)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import ROOT
from dampertwin.design import load
from dampertwin.excitation import Excitation
from dampertwin.jit import lazy_njit
from dampertwin.solver import integrate, rhs_signature
from dampertwin.truth import gas as gs
from dampertwin.truth import params as tp
from dampertwin.truth import plate
from dampertwin.truth.run import simulate

NOMINAL = ROOT / "conf" / "lab" / "nominal.yaml"


def truth(**effects):
    v = tp.nominal(load(NOMINAL))
    return tp.derive(v, effects), {"P0": v["P0"], "V_gas0": v["V_gas0"], "T": v["T"]}, v


@pytest.fixture(scope="module")
def cycle():
    """Three cycles of a 4 Hz, +-15 mm sine on the damper at 1.2 A (gas
    dissolution off: its slow drift is not a cycle's), sampled at 20 kHz."""
    p, rest, _ = truth(gas_dissolution=False)
    ex = Excitation.sine(0.015, 4.0, 0.75, ramp=0.25)
    return simulate(p, ex, "damper", current=1.2, rest=rest, rate=20_000.0), ex


def test_oil_mass_is_conserved_over_cycles(cycle):
    r, _ = cycle
    assert r.ok
    m = r["oil mass [kg]"]
    assert np.max(np.abs(m - m[0])) / m[0] < 1e-7
    assert np.ptp(r["p rebound [Pa]"]) > 5e5  # the cycle really moved oil


def test_dissipated_energy_per_cycle_equals_the_work_of_the_actuator(cycle):
    """Over the last full cycle, the work of the actuator's force on the tube
    (integral of F du) equals the energy dissipated inside (throttling,
    friction, valve and fixture damping, gas heat) minus the solenoid's
    mechanical work on the pilot, within 1 %."""
    r, ex = cycle
    t = r.time
    last = t >= t[-1] - 0.25
    F, u = r["actuator force [N]"][last], r["displacement [m]"][last]
    work = np.trapezoid(F, u)
    diss = np.trapezoid(r["dissipated power [W]"][last] - r["magnetic power [W]"][last], t[last])
    assert work > 20.0  # a damper absorbs energy
    assert abs(work - diss) / work < 0.01, (work, diss)


def test_static_equilibrium_at_rest_on_the_gas_precharge():
    """At rest every chamber holds the precharge and the rod carries the gas
    force (P0 - P_atm) x rod area, in compression; nothing drifts."""
    p, rest, v = truth()
    ex = Excitation(0.0, 0.01, np.zeros(51), np.zeros(51))
    r = simulate(p, ex, "damper", current=0.9, rest=rest, rate=1000.0)
    A_rod = math.pi / 4 * v["D_R"] ** 2
    F0 = -(rest["P0"] - v["oil.P_ATM"]) * A_rod
    for ch in ("p rebound [Pa]", "p compression [Pa]", "p third tube [Pa]", "p reserve [Pa]"):
        assert np.max(np.abs(r[ch] - rest["P0"])) < 20.0, ch  # Pa
    assert np.max(np.abs(r["rod force [N]"] - F0)) < 0.05
    assert np.max(np.abs(r["lift piston_rebound [m]"])) < 2e-6 and np.max(np.abs(r["lift main stage [m]"])) < 2e-6


# Roark's Formulas for Stress and Strain (7th ed.), table 11.2 shortcut coefficients (Wahl & Lobo 1930, nu 0.3):
# annular plate, outer edge free, inner edge fixed, y_max = K W a^2 / (E t^3) under a ring load W at the outer
# edge, y_max = K q a^4 / (E t^3) under a uniform pressure q.
ROARK_RING = {1.25: 0.00510, 1.5: 0.0249, 2.0: 0.0877, 3.0: 0.209, 4.0: 0.293, 5.0: 0.350}
ROARK_UNIFORM = {1.25: 0.00231, 2.0: 0.0938, 5.0: 0.564}


@pytest.mark.parametrize("ratio", sorted(ROARK_RING))
def test_annular_plate_edge_deflection_matches_roark(ratio):
    a, t, E = 0.013, 2e-4, 206e9
    W, q = 10.0, 1e5
    y = plate.edge_deflection(a, a / ratio, t, E, 0.3, W=W)
    assert y == pytest.approx(ROARK_RING[ratio] * W * a * a / (E * t ** 3), rel=0.01)
    if ratio in ROARK_UNIFORM:
        y = plate.edge_deflection(a, a / ratio, t, E, 0.3, q=q)
        assert y == pytest.approx(ROARK_UNIFORM[ratio] * q * a ** 4 / (E * t ** 3), rel=0.01)


def test_stack_area_is_the_swept_volume_per_lift():
    """Maxwell-Betti: the pressure-equivalent area k w_q / q equals the
    volume the plate sweeps over the loaded ring per unit edge lift under the
    edge load (integrated numerically from the deflection shape)."""
    a, b, r1, t = 0.013, 0.008, 0.009, 3e-4
    s = plate.stack(a, b, t, 1, 206e9, 0.3, r1)
    r = np.linspace(r1, a, 801)
    w = np.array([plate.edge_deflection(a, b, t, 206e9, 0.3, W=1.0, at=x) for x in r])
    swept = np.trapezoid(w * 2 * np.pi * r, r) / w[-1]
    assert s["area"] == pytest.approx(swept, rel=1e-4)


def test_coil_step_response_is_an_rl_circuit():
    """A command far above what the supply can drive (100 A against U / R = 3.4 A) saturates the driver
    at its supply voltage from zero current: the coil sees a voltage step, i(t) = U/R (1 - exp(-R t / L))."""
    p, rest, v = truth()
    ex = Excitation(0.0, 0.001, np.zeros(31), np.zeros(31))
    r = simulate(p, ex, "damper", current=100.0, rest=rest, rate=5000.0, settle=0.0, start_current=0.0)
    p0 = {k: v.get(k, tp.TRUTH_NOMINAL.get(k)) for k in ("active_valve.U_MAX", "active_valve.R", "active_valve.L")}
    U, R, L = p0["active_valve.U_MAX"], p0["active_valve.R"], p0["active_valve.L"]
    i = U / R * (1 - np.exp(-R * r.time / L))
    assert np.max(np.abs(r["coil current [A]"] - i)) < 1e-4 * U / R


def test_without_its_driver_the_coil_carries_the_command():
    """Driver off (the truth without driver and coil dynamics): an ideal current source. From a start at
    zero current the coil carries the command at once, and at a constant command the damper force equals
    the driver's once the driver has settled (its steady state has no error)."""
    ex = Excitation.sine(0.01, 3.0, 2 / 3)
    out = {}
    for on in (True, False):
        p, rest, _ = truth(current_driver=on, gas_dissolution=False)
        out[on] = simulate(p, ex, "damper", current=0.9, rest=rest, rate=5000.0, start_current=0.0)
    assert np.all(out[False]["coil current [A]"] == 0.9)
    i_on = out[True]["coil current [A]"]
    assert abs(i_on[0] - 0.9) < 1e-3  # the driver's settle has reached the command before the record
    f_on, f_off = out[True]["rod force [N]"], out[False]["rod force [N]"]
    assert np.max(np.abs(f_off - f_on)) < 1e-4 * np.max(np.abs(f_on)), np.max(np.abs(f_off - f_on))
    assert np.ptp(f_on) > 100.0  # the valve really carried flow


def test_current_driver_reaches_the_command_with_finite_bandwidth():
    """Driver on, from zero current: the current reaches the command
    (no static error) after a rise time of the order of L / (R + KP)."""
    p, rest, _ = truth()
    ex = Excitation(0.0, 0.001, np.zeros(31), np.zeros(31))
    r = simulate(p, ex, "damper", current=1.0, rest=rest, rate=20000.0, settle=0.0, start_current=0.0)
    i = r["coil current [A]"]
    t63 = r.time[np.argmax(i >= 0.632)]
    assert abs(i[-1] - 1.0) < 1e-3
    assert 0.3e-4 < t63 < 3e-3


@lazy_njit(rhs_signature(), cache=False)  # calls gas.reserve: no stale cache across edits
def _gas_bench(t, y, p, ex, aux, dy, out):
    """The reserve gas alone, its volume prescribed: V = V0 (1 - 0.3 min(t / t_c, 1))."""
    V0, t_c = p[len(gs.PARAMS)], p[len(gs.PARAMS) + 1]
    f = min(t / t_c, 1.0)
    V = V0 * (1.0 - 0.3 * f)
    dV = -0.3 * V0 / t_c if t < t_c else 0.0
    P = y[gs.M_G] * p[gs.R_S] * y[gs.T_G] / V
    gs.reserve(y, 0, p, 0, P, V, dV, 1e-4, 300.0, dy)
    out[0] = P
    out[1] = V


@pytest.mark.parametrize("tau, t_c, exponent", [(1e-4, 1.0, 1.0), (1e4, 1e-3, 1.4)])
def test_reserve_gas_is_polytropic_between_isothermal_and_adiabatic(tau, t_c, exponent):
    """A fast wall exchange (tau << compression time) keeps P V constant,
    none (tau >> compression time) keeps P V^gamma constant, gamma =
    (c_v + R) / c_v = 1.4 for nitrogen."""
    R, cv, V0, P0 = 296.8, 743.0, 8e-5, 4e5
    m = P0 * V0 / (R * 300.0)
    q = np.zeros(len(gs.PARAMS) + 2)
    q[gs.R_S], q[gs.C_V], q[gs.H], q[gs.HEAT] = R, cv, m * cv / tau, 1.0
    q[len(gs.PARAMS)], q[len(gs.PARAMS) + 1] = V0, t_c
    y0 = np.array([0.0, m, 300.0, 0.0])
    out, _, st = integrate(_gas_bench, q, np.zeros((2, 2)), np.zeros(1), y0, np.array([0.0, 2 * t_c]),
                           scales=np.array([1.0, 1e-5, 1.0, 1e-6]), n_rhs_out=2, rtol=1e-9)
    assert st.ok
    P, V = out[-1]
    assert P * V ** exponent == pytest.approx(P0 * V0 ** exponent, rel=0.002)
    other = 1.4 if exponent == 1.0 else 1.0
    assert P * V ** other != pytest.approx(P0 * V0 ** other, rel=0.05)


def test_fixture_resonates_and_off_means_a_rigid_frame():
    """With the fixture the load cell rings at its resonance
    sqrt(K_F / M_F) / 2 pi after a force step; switched off, the load cell
    reads the damper's force bit for bit."""
    p, rest, v = truth(fixture=False)
    ex = Excitation.sine(0.01, 4.0, 0.3, ramp=0.1)
    r = simulate(p, ex, "damper", current=0.9, rest=rest, rate=10_000.0)
    assert np.array_equal(r["rod force [N]"], r["actuator force [N]"])
    p, rest, v = truth()
    r = simulate(p, ex, "damper", current=0.9, rest=rest, rate=20_000.0)
    ring = r["rod force [N]"] - r["actuator force [N]"]
    f, P = __import__("scipy.signal", fromlist=["welch"]).welch(ring, fs=20_000.0, nperseg=2048)
    f_n = math.sqrt(v["fixture.K_F"] / v["fixture.M_F"]) / (2 * math.pi)
    assert abs(f[np.argmax(P * (f > 100))] - f_n) < 0.05 * f_n


# --- virtual work and the walls (review findings: a part's pressure area must sweep its volume; a wall between
# two oil chambers is loaded by the pressure difference across it) ---------------------------------------------

def _damper_state(**effects):
    """(p, y, ex) of the damper at rest at 1.2 A with every valve pressed
    2 um into its seat (no flow: the pressure forces are the areas' alone)
    and the chambers at different pressures."""
    from dampertwin.truth import chambers as ch
    from dampertwin.truth import intake as ik
    from dampertwin.truth import shims as sh
    from dampertwin.truth import solenoid as sv
    from dampertwin.truth.layout import CURRENT, EX_DT, EX_T0, PO, SO
    from dampertwin.truth.run import _rest_damper

    p, rest, _ = truth(**effects)
    ex = Excitation.sine(0.01, 2.0, 0.5)
    p[PO["run"] + CURRENT] = 1.2
    p[PO["run"] + EX_T0], p[PO["run"] + EX_DT] = ex.t0, ex.dt
    y = _rest_damper(p, "damper", 0.0, rest["T"], rest["P0"], rest["V_gas0"])
    for block, x in (("piston_rebound", sh.X), ("piston_intake", ik.X), ("base_compression", sh.X),
                     ("base_intake", ik.X)):
        y[SO[block] + x] = -2e-6
    y[SO["active_valve"] + sv.XM] = -2e-6
    y[SO["active_valve"] + sv.XP] = -2e-6
    c = SO["chambers"]
    y[c + ch.PR], y[c + ch.PC], y[c + ch.PB] = 3.1e6, 2.2e6, 2.7e6
    y[SO["active_valve"] + sv.PK] = 2.4e6
    return p, y, ex.array()


def _parts():
    """(name, state offset of its lift, state offset of its velocity, its mass) per moving part."""
    from dampertwin.truth import intake as ik
    from dampertwin.truth import shims as sh
    from dampertwin.truth import solenoid as sv
    from dampertwin.truth.layout import PO, SO

    out = [(b, SO[b] + m.X, SO[b] + m.V, PO[b] + m.M) for b, m in
           (("piston_rebound", sh), ("piston_intake", ik), ("base_compression", sh), ("base_intake", ik))]
    av, ao = SO["active_valve"], PO["active_valve"]
    return out + [("main stage", av + sv.XM, av + sv.VM, ao + sv.M_M), ("pilot", av + sv.XP, av + sv.VP, ao + sv.M_P)]


def _volumes(p, y):
    from dampertwin.truth.damper import volumes

    V = volumes(y, p, 0.0, 0.0)
    return {"r": V[0], "c": V[2], "b": V[4], "k": V[6], "sw": V[8]}


def test_every_pressure_loaded_area_sweeps_its_volume():
    """Virtual work: for each moving part and each chamber, the force the
    chamber's pressure puts on the part per Pa equals the volume the part
    adds to that chamber per metre of lift (otherwise a stroke of the part
    creates or destroys energy); and what a lift adds to the chambers it
    takes from the reservoir (the oil spaces' total volume is fixed). The
    walls are rigid here: the third tube's bulge couples the reservoir's
    pressure to P_b (see the next test)."""
    from dampertwin.truth import chambers as ch
    from dampertwin.truth.damper import rhs_damper
    from dampertwin.truth.layout import N_OUT, SO, state_names

    p, y, ex = _damper_state(wall_compliance=False)
    n = len(state_names("damper"))
    c, av = SO["chambers"], SO["active_valve"]
    from dampertwin.truth import solenoid as sv
    chambers = {"r": c + ch.PR, "c": c + ch.PC, "b": c + ch.PB, "k": av + sv.PK}

    def accel(yy, iv):
        dy, out = np.zeros(n), np.zeros(N_OUT)
        rhs_damper(0.0, yy, p, ex, np.zeros(1), dy, out)
        return dy[iv]

    checked = 0
    for name, ix, iv, im in _parts():
        h = 1e-7
        yp, ym = y.copy(), y.copy()
        yp[ix] += h
        ym[ix] -= h
        Vp, Vm = _volumes(p, yp), _volumes(p, ym)
        dV = {k: (Vp[k] - Vm[k]) / (2 * h) for k in Vp}
        assert abs(dV["r"] + dV["c"] + dV["b"] + dV["k"] - dV["sw"]) < 1e-9, name
        for chamber, iP in chambers.items():
            dP = 1e3
            yp, ym = y.copy(), y.copy()
            yp[iP] += dP
            ym[iP] -= dP
            area = p[im] * (accel(yp, iv) - accel(ym, iv)) / (2 * dP)
            assert area == pytest.approx(dV[chamber], rel=1e-4, abs=1e-9), (name, chamber, area, dV[chamber])
            checked += abs(area) > 1e-7
    assert checked >= 8  # every part is loaded by at least one chamber


def test_the_walls_take_from_one_chamber_what_they_give_the_next():
    """The pressure tube's wall bends with the pressure difference across it:
    raising the third tube's pressure squeezes the rebound chamber by the
    Lame compliance times its bore volume, and no pressure change alters
    the oil spaces' total volume (the steel is taken incompressible); with
    the same pressure on both sides of every wall no chamber stretches."""
    from dampertwin.truth import chambers as ch
    from dampertwin.truth.layout import PO, SO

    p, y, _ = _damper_state()
    q, _, _ = _damper_state(wall_compliance=False)
    c, co = SO["chambers"], PO["chambers"]
    total = lambda V: V["r"] + V["c"] + V["b"] + V["k"] - V["sw"]  # noqa: E731
    base = _volumes(p, y)
    for i in (ch.PR, ch.PC, ch.PB):
        yy = y.copy()
        yy[c + i] += 1e6
        assert abs(total(_volumes(p, yy)) - total(base)) < 1e-12
    yy = y.copy()
    yy[c + ch.PB] += 1e6
    squeeze = _volumes(p, yy)["r"] - base["r"]
    bore = p[co + ch.A_B] * p[co + ch.L_R0]
    assert squeeze == pytest.approx(-1e6 * p[co + ch.KAPPA_PT] * bore, rel=1e-9)
    assert squeeze < 0
    yy = y.copy()
    yy[c + ch.PR] = yy[c + ch.PC] = yy[c + ch.PB] = p[co + ch.P_W]  # the reservoir at its rest pressure
    on, off = _volumes(p, yy), _volumes(q, yy)
    for k in on:
        assert on[k] == pytest.approx(off[k], rel=1e-12, abs=1e-15), k


def test_the_coupled_wall_rates_solve_the_three_balances():
    """walled_rates returns the rates that satisfy all three mass balances."""
    from dampertwin.truth.chambers import walled_rates

    rng = np.random.default_rng(3)
    for _ in range(20):
        a_r, a_c, a_b, W_r, W_c, W_t = rng.uniform(1e-14, 1e-12, 6)
        b_r, b_c, b_b = rng.normal(0, 1e-5, 3)
        r, c, b = walled_rates(a_r, b_r, a_c, b_c, a_b, b_b, W_r, W_c, W_t)
        assert (a_r + W_r) * r - W_r * b == pytest.approx(b_r, rel=1e-9, abs=1e-20)
        assert (a_c + W_c) * c - W_c * b == pytest.approx(b_c, rel=1e-9, abs=1e-20)
        assert (a_b + W_r + W_c + W_t) * b - W_r * r - W_c * c == pytest.approx(b_b, rel=1e-9, abs=1e-20)


@pytest.mark.parametrize("kind", ["piston_rebound", "piston_intake"])
def test_a_wide_open_valve_feels_the_jet_not_the_whole_drop(kind):
    """The ports (holes) lie in series before the stack (disc): when the
    curtain is ten times wider than them, nearly the whole drop is theirs,
    the face under the stack sits near the downstream pressure, and the
    opening force is the jet's momentum flux (about 2 CD^2 A_port dp) plus a
    small rest, well below the pressure-equivalent area times the whole
    drop; counting the port head twice gives more than that product."""
    from dampertwin.truth import intake as ik
    from dampertwin.truth import shims as sh
    from dampertwin.truth.layout import PO

    p, _, _ = truth()
    p = p.copy()
    o = PO[kind]
    m = sh if kind == "piston_rebound" else ik
    port = p[o + sh.A_PORT] if m is sh else p[o + ik.A_HOLE]
    radius = p[o + sh.R_S] if m is sh else p[o + ik.R_IN]
    x = 10.0 * port / (2 * math.pi * radius)  # curtain ten times the ports' area
    p[o + m.X_MAX] = 10.0 * x  # no lift stop in the way
    y, dy = np.zeros(3), np.zeros(3)
    y[m.X] = x
    dp, rho, mu = 2e6, 850.0, 0.01
    if m is sh:
        area = p[o + sh.A_EQ]
        sh.shim_valve(y, 0, p, o, dp + 1e5, 1e5, rho, mu, dy)
        pressure_force = dy[sh.V] * p[o + sh.M] + sh.elastic_force(x, p, o)
    else:
        area = p[o + ik.A_P]
        ik.intake_valve(y, 0, p, o, dp + 1e5, 1e5, rho, mu, dy)
        pressure_force = dy[ik.V] * p[o + ik.M] + p[o + ik.F_S] + p[o + ik.K_S] * x
    assert 0.0 < pressure_force < 0.5 * area * dp, (pressure_force, area * dp)


@pytest.mark.parametrize("payne", [True, False])
def test_the_rubber_mount_is_passive_at_any_state(payne):
    """Power balance of the top mount at random states, also while the
    Payne factor changes: the power put in, F dX/dt, is the rate of the
    stored energy (backbone and branches, phi K_j y_j^2 / 2) plus the
    dissipation it reports, which is >= 0 (a stiffness that recovers as
    the amplitude falls must not release energy)."""
    from dampertwin.truth import mount as mt
    from dampertwin.truth.layout import PO

    p, _, _ = truth(payne=payne)
    o = PO["mount"]
    rng = np.random.default_rng(7)
    K = np.array([p[o + mt.K_1 + j] for j in range(mt.N_BRANCHES)])
    for _ in range(50):
        y = np.zeros(len(mt.STATES))
        y[: mt.N_BRANCHES] = rng.normal(0, 3e-4, mt.N_BRANCHES)
        y[mt.X_MEAN] = rng.normal(0, 1e-4)
        y[mt.MS] = rng.uniform(0, 2e-7)
        X, Xd = rng.normal(0, 5e-4), rng.normal(0, 0.05)
        dy = np.zeros_like(y)
        F, loss = mt.mount(y, 0, p, o, X, Xd, dy)
        phi, dphi = mt.payne_factor(y[mt.MS], p, o)
        h = 1e-14
        assert dphi == pytest.approx((mt.payne_factor(y[mt.MS] + h, p, o)[0]
                                      - mt.payne_factor(y[mt.MS] - h, p, o)[0]) / (2 * h), rel=1e-4, abs=1e-3)
        y_b = y[: mt.N_BRANCHES]
        stored_rate = ((p[o + mt.K_E] * X + p[o + mt.K_E3] * X ** 3) * Xd + phi * np.sum(K * y_b * dy[: mt.N_BRANCHES])
                       + 0.5 * dphi * dy[mt.MS] * np.sum(K * y_b ** 2))
        assert loss >= 0.0
        assert F * Xd == pytest.approx(stored_rate + loss, rel=1e-9, abs=1e-9 * (abs(F * Xd) + loss))
