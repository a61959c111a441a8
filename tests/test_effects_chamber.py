"""Physics of the chamber / friction effects of the library (issue 34,
acceptance 2): oil_thermal acts on the oil's modulus only and adds the oil's
expansion and the gas's heating; aeration carries free air as a state with
release and dissolution at finite rates; rod_friction_asymmetric is not a
force offset. Direct right-hand-side calls and short runs."""

from __future__ import annotations

import numpy as np
import pytest

from dampertwin import Excitation, simulate
from dampertwin.design import load
from dampertwin.model import layout as L
from dampertwin.model.active_valve import pack_map
from dampertwin.model.chambers import moduli
from dampertwin.model.damper import RHS_BY_CFG
from dampertwin.model.params import pack

from conftest import BASELINE


@pytest.fixture(scope="module")
def base():
    return load(BASELINE)


def _on(design, effect, **extra):
    ov = {e.key: e.typical for e in design.effect_parameters(effect)}
    ov.update(extra)
    ov[f"effects.{effect}"] = True
    return design.with_overrides(ov)


def _rhs_at_rest(design, cfg_name="damper", edit=None):
    """One right-hand-side call of the extended configuration at its rest
    state (no motion), ``edit(y, p)`` changing the state first. Returns
    (y, p, dy, out)."""
    p = pack(design).copy()
    cfg = L.variant(L.CONFIGURATIONS[cfg_name], p)
    ex = Excitation.from_samples(np.linspace(0.0, 0.1, 11), np.zeros(11))
    p[L.P.EX_T0], p[L.P.EX_DT] = ex.t0, ex.dt
    y = L.initial_state(p, cfg)
    if edit:
        edit(y, p)
    dy, out = np.zeros_like(y), np.zeros(L.N_OUT)
    aux = pack_map(design.pq_map.currents, design.pq_map.dps, design.pq_map.flow)
    RHS_BY_CFG[cfg](0.0, y, p, ex.array(), aux, dy, out)
    return y, p, dy, out


# ------------------------------------------------------------ oil_thermal
def _chamber_moduli(design, P, K_oil, T):
    p = pack(design)
    return np.array(moduli(p, P, P, P, P, K_oil, T))  # the reserve at P too


def _rhs_moduli(design, P, T):
    """The chamber moduli [Pa] the assembled right-hand side uses, read at
    rest with every chamber and the reserve at P and the oil at T != T_amb:
    there dP_i/dt = K_i beta_T dT/dt (no flow, no motion)."""
    def state(y, p):
        y[L.EB_DAMPER + L.EX.T_oil] = T
        y[L.S.P_r] = y[L.S.P_c] = y[L.S.P_b] = P
        y[L.S.V_g] = p[L.P.V_G0] * (p[L.P.P0] * T / p[L.P.TEMP] / P) ** (1.0 / p[L.P.GAMMA])
    _, p, dy, out = _rhs_at_rest(design, edit=state)
    assert abs(out[L.O.P_RES] / P - 1.0) < 1e-12
    src = p[L.P.TH_BETA] * dy[L.EB_DAMPER + L.EX.T_oil]
    assert abs(src) > 0
    return np.array([dy[L.S.P_r], dy[L.S.P_c], dy[L.S.P_b]]) / src


@pytest.mark.parametrize("dT", [-20.0, 40.0])
def test_thermal_law_acts_on_the_oils_modulus_only(base, dT):
    """Limit case (no gas, no wall): the chamber modulus of the assembled
    model is the oil law K_oil0 (1 - c_K dT). With the wall on, the wall's
    compliance 1/K - 1/K_oil stays what it is at T0 (the old law, scaling the
    whole chamber modulus, changes it by the factor)."""
    from dampertwin.model.oil_thermal import modulus_factor
    d = _on(base, "oil_thermal")
    c_K, K0, T0 = d["oil_thermal.c_K"], d["oil.K_oil"], d["oil.T"]
    K_T = K0 * modulus_factor(c_K, dT)
    assert K_T == pytest.approx(K0 * (1.0 - c_K * dT), rel=1e-15)
    bare = d.with_overrides({"effects.gas_content": False, "effects.wall_compliance": False,
                             "effects.cavitation": False})
    np.testing.assert_allclose(_rhs_moduli(bare, 3e5, T0 + dT), K_T, rtol=1e-9)
    wall = d.with_overrides({"effects.gas_content": False, "effects.cavitation": False})
    for P in (2e5, 2e6):
        hot, ref = _rhs_moduli(wall, P, T0 + dT), _chamber_moduli(wall, P, K0, T0)
        # rebound chamber: no wall compliance; compression and third tube: the same wall as at T0
        assert hot[0] == pytest.approx(K_T, rel=1e-9)
        assert ref[1] < 0.95 * K0  # the wall is a visible part of the compliance
        np.testing.assert_allclose(1.0 / hot[1:] - 1.0 / K_T, 1.0 / ref[1:] - 1.0 / K0, rtol=1e-6)


def test_thermal_gas_follows_the_ideal_gas_law(base):
    """With the oil's modulus held temperature-independent (c_K = 0) and no
    free gas in the emulsion (chi = 0), a change of temperature does not change
    any chamber modulus; the reserve gas at fixed volume goes up by T/T0 and
    the emulsion's free gas (eq. 4.15, T/T_ref) softens the chamber."""
    d = _on(base, "oil_thermal", **{"oil_thermal.c_K": 0.0, "oil_thermal.beta_T": 0.0})
    T0 = d["oil.T"]
    plain = d.with_overrides({"oil.chi": 0.0})
    K0 = plain["oil.K_oil"]
    for P in (2e5, 2e6):
        assert np.array_equal(_chamber_moduli(plain, P, K0, T0 + 30.0), _chamber_moduli(plain, P, K0, T0))
    assert d["oil.P_sat"] > 5e5
    for P in (2e5, 5e5):  # free gas below P_sat: warmer gas, larger volume, softer chamber
        assert np.all(_chamber_moduli(d, P, K0, T0 + 30.0) < _chamber_moduli(d, P, K0, T0))

    def warm(y, p):
        y[L.EB_DAMPER + L.EX.T_oil] = T0 + 30.0
    _, p, _, out = _rhs_at_rest(d, edit=warm)
    assert out[L.O.P_RES] == pytest.approx(d["oil.P_0"] * (T0 + 30.0) / T0, rel=1e-14)
    _, _, _, cold = _rhs_at_rest(d)
    assert cold[L.O.P_RES] == d["oil.P_0"]


def test_thermal_expansion_fills_the_chambers_storage(base):
    """Damper at rest, oil 20 K above the ambient, cooling: no flow, no
    motion, so each chamber's storage V/K dP/dt equals its oil's volume
    change beta_T V dT/dt (volume balance eq. 4.9 with the expansion
    source), and dT/dt is the cooling rate -hA dT / C_th."""
    d = _on(base, "oil_thermal")
    T0 = d["oil.T"]

    def warm(y, p):
        y[L.EB_DAMPER + L.EX.T_oil] = T0 + 20.0
        y[L.S.P_r] = y[L.S.P_c] = y[L.S.P_b] = p[L.P.P0] * (T0 + 20.0) / T0  # balanced with the warm gas
    y, p, dy, out = _rhs_at_rest(d, edit=warm)
    dT = dy[L.EB_DAMPER + L.EX.T_oil]
    assert dT == pytest.approx(-d["oil_thermal.hA"] * 20.0 / d["oil_thermal.C_th"], rel=1e-12)
    beta = d["oil_thermal.beta_T"]
    assert max(abs(out[k]) for k in (L.O.Q0, L.O.Q1, L.O.Q2, L.O.Q3, L.O.Q_BP, L.O.Q_A)) < 1e-15
    V_r, V_c = p[L.P.A_R] * p[L.P.L_R0], p[L.P.A_B] * p[L.P.L_C0]
    for st, V in ((L.O.ST_R, V_r), (L.O.ST_C, V_c), (L.O.ST_B, p[L.P.V_B])):
        assert out[st] == pytest.approx(beta * V * dT, rel=1e-9)
    assert dy[L.S.P_c] < 0.0  # cooling oil shrinks: the pressure falls


def test_thermal_expansion_moves_the_oil_into_the_reserve(base):
    """Warm-up run: with the expansion the reserve gas ends compressed by
    the oil's volume growth beta_T V_oil dT (V_oil the three chambers' oil),
    read from the reserve pressure through the gas law P_res = P0 (V0/V)^G T/T0."""
    ex = Excitation.sine(0.01, 8.0, 3.0)
    runs = {}
    for beta in (0.0, 7e-4):
        d = _on(base, "oil_thermal", **{"oil_thermal.C_th": 400.0, "oil_thermal.beta_T": beta})
        r = simulate(d, ex, "damper", current=1.6, rate=2000.0)
        assert r.ok
        T, P = r["oil temperature [K]"][-1], r["p reserve [Pa]"][-1]
        p = pack(d)
        V_g = p[L.P.V_G0] * (p[L.P.P0] * T / p[L.P.TEMP] / P) ** (1.0 / p[L.P.GAMMA])
        runs[beta] = (V_g, T)
    p = pack(base)
    V_oil = p[L.P.A_R] * p[L.P.L_R0] + p[L.P.A_B] * p[L.P.L_C0] + p[L.P.V_B]  # stroke 0 at the end
    dT = runs[7e-4][1] - base["oil.T"]
    assert dT > 1.0
    assert runs[0.0][0] - runs[7e-4][0] == pytest.approx(7e-4 * V_oil * dT, rel=0.03)


# ------------------------------------------------------------ aeration
def _final_state(design, ex, h_max=1e-3, **values):
    """Integrate the damper configuration (packed parameters ``values`` set
    directly, past the design's bounds) and return (final state, last
    outputs, packed p)."""
    from dampertwin import simulation as sim
    from dampertwin.solver import integrate
    cfg, p = sim._setup(design, ex, "damper", 1.6, None, None, None)
    p = p.copy()
    for k, v in values.items():
        p[L.P[k]] = v
    t_out = sim._time_grid(ex, None, 500.0)
    aux = pack_map(design.pq_map.currents, design.pq_map.dps, design.pq_map.flow)
    kw, rhs = sim._problem("damper", cfg, p[None, :], ex.array(), aux, t_out)
    out, y, stats = integrate(rhs, p, ex.array(), aux, L.initial_state(p, cfg), t_out, rtol=1e-4, h_max=h_max,
                              method="rodas4", **kw)
    assert np.all(np.isfinite(out))
    return y, out[-1], p


def _air_equilibrium(y, out, p):
    """(V_a, V_eq) at the end of a run: V_eq = V_oil ramp(alpha0 + H (P0 - P)/P_atm)."""
    from dampertwin.model.aeration import equilibrium_content, free_air
    V_a, P = y[L.EB_DAMPER + L.EX.V_air], out[L.O.P_C]
    V_c = p[L.P.A_B] * (p[L.P.L_C0] + out[L.O.S])
    V_oil = V_c - free_air(V_a, P, p[L.P.P_ATM], p[L.P.AE_N])
    return V_a, V_oil * equilibrium_content(P, p[L.P.P0], p[L.P.P_ATM], p[L.P.AE_ALPHA0], p[L.P.AE_H])


def test_aeration_equilibrium_is_the_boyle_henry_law(base):
    """At its Henry equilibrium the free air does not move (dV_a/dt = 0) and
    the chamber modulus is Wood's law of oil and x = alpha_eq(P) (P_atm/P)^(1/n)
    free air per oil volume; with H = 0 that is the static Boyle law
    x = alpha0 (P_atm/P)^(1/n)."""
    from dampertwin.model.aeration import aerated_chamber, equilibrium_content
    P0, P_atm, K, V_c = 4.0e5, 1.01325e5, 7.0e8, 1.0e-4
    for H in (0.0, 0.09):
        for n in (1.0, 1.4):
            for P in (0.6e5, 2.0e5, 4.0e5, 8.0e5):
                a_eq = equilibrium_content(P, P0, P_atm, 0.01, H)
                if H == 0.0:
                    assert a_eq == 0.01
                x = a_eq * (P_atm / P) ** (1.0 / n)  # free air volume per oil volume
                V_a = a_eq * V_c / (1.0 + x)  # its amount at P_atm, at equilibrium
                K_eff, src, dV_a = aerated_chamber(K, P, V_c, V_a, P0, P_atm, 0.01, n, H, 0.1, 2.0)
                assert abs(dV_a) < 1e-12 * V_c and abs(src) < 1e-12 * V_c
                phi = x / (1.0 + x)
                assert K_eff == pytest.approx(1.0 / ((1.0 - phi) / K + phi / (n * P)), rel=1e-12)
    # below the precharge the saturated oil gives air off, above it the entrained air dissolves
    assert equilibrium_content(2e5, P0, P_atm, 0.01, 0.09) > 0.01 > equilibrium_content(4.05e5, P0, P_atm, 0.01, 0.09)
    assert equilibrium_content(20e5, P0, P_atm, 0.01, 0.09) == 0.0


def test_aeration_conserves_the_chamber_volume(base):
    """Mid-stroke, the air away from its equilibrium (released and
    dissolving): the oil's volume change (outflow and compression) plus the
    air's (release and compression) equals the chamber's dV_c/dt."""
    from dampertwin.model.aeration import free_air
    d = _on(base, "aeration")
    for frac, P_c in ((0.3, 1.5e5), (3.0, 9.0e5)):
        p = pack(d).copy()
        cfg = L.variant(L.CFG_DAMPER, p)
        ex = Excitation.sine(0.005, 16.0, 0.25)
        p[L.P.EX_T0], p[L.P.EX_DT] = ex.t0, ex.dt
        y = L.initial_state(p, cfg)
        y[L.S.P_c] = P_c
        o = L.EB_DAMPER + L.EX.V_air
        y[o] *= frac
        dy, out = np.zeros_like(y), np.zeros(L.N_OUT)
        aux = pack_map(d.pq_map.currents, d.pq_map.dps, d.pq_map.flow)
        RHS_BY_CFG[cfg](0.13, y, p, ex.array(), aux, dy, out)
        sd = out[L.O.V]
        assert abs(sd) > 0.05 and abs(dy[o]) > 0
        P_res = out[L.O.P_RES]
        K = moduli(p, y[L.S.P_r], P_c, y[L.S.P_b], P_res, p[L.P.K_OIL], p[L.P.TEMP])[1]
        n, P_atm = p[L.P.AE_N], p[L.P.P_ATM]
        V_c = p[L.P.A_B] * (p[L.P.L_C0] + out[L.O.S])
        V_air = free_air(y[o], P_c, P_atm, n)
        dP = dy[L.S.P_c]
        Q_out = -(out[L.O.Q0] - out[L.O.Q1]) + (out[L.O.Q2] - out[L.O.Q3])
        dV_oil = -Q_out - (V_c - V_air) / K * dP
        dV_air = (P_atm / P_c) ** (1.0 / n) * dy[o] - V_air / (n * P_c) * dP
        assert dV_oil + dV_air == pytest.approx(p[L.P.A_B] * sd, rel=1e-9)
        assert (dy[o] > 0) == (frac < 1.0)  # released below, dissolved above the equilibrium


def test_aeration_has_memory(base):
    """A quasi-static cycle (0.05 Hz) ends with the free air at its Henry
    equilibrium; a fast one (16 Hz, 2 cycles, ending at the start of a
    rebound stroke) ends away from it, holding the air the first rebound
    stroke released (history-dependent stiffness, which a static gas content
    cannot give). With tau -> 0 the fast cycle ends at the equilibrium too."""
    d = _on(base, "aeration")
    y, out, p = _final_state(d, Excitation.sine(0.005, 0.05, 20.0), h_max=0.02)
    V_slow, eq = _air_equilibrium(y, out, p)
    assert V_slow == pytest.approx(eq, rel=0.05)  # lag of the dissolution ~ 2 pi f tau_dis of the swing
    y, out, p = _final_state(d, Excitation.sine(0.005, 16.0, 2 / 16.0))
    V_fast, eq = _air_equilibrium(y, out, p)
    # away from the equilibrium at its pressure (the release lags the rebound's low pressure) and above the
    # quasi-static content (air released in the earlier rebound stroke not yet dissolved)
    assert abs(V_fast / eq - 1.0) > 0.5 and V_fast > 1.5 * V_slow
    y, out, p = _final_state(d, Excitation.sine(0.005, 16.0, 2 / 16.0), AE_TREL=1e-5, AE_TDIS=1e-5)
    V_q, eq = _air_equilibrium(y, out, p)
    assert V_q == pytest.approx(eq, rel=0.01)


def test_aeration_without_air_is_the_model_without_aeration(base):
    """Limit case: alpha0 = H = 0 (no entrained air, oil that dissolves
    none) is the model without the effect, to the integrator's tolerance
    (16 Hz +-5 mm at rtol 1e-8: 3e-5 N; the extra state alone moves the
    steps, 0.85 N at rtol 1e-4). Fails if the equilibrium ramp is not
    exactly 0 at full dissolution (a rounding that left eps / 4 of air:
    ~1 N at any rtol); and the ramp is C1 and exact outside its rounding."""
    from dampertwin.model.aeration import ALPHA_EPS, ramp
    ex = Excitation.sine(0.005, 16.0, 0.5)
    off = simulate(base, ex, "damper", current=1.6, rtol=1e-8)
    on = simulate(_on(base, "aeration", **{"aeration.alpha0": 0.0, "aeration.H": 0.0}), ex, "damper", current=1.6,
                  rtol=1e-8)
    F_off, F_on = off["rod force [N]"], on["rod force [N]"]
    assert on.ok and off.ok
    assert np.max(np.abs(F_on - F_off)) < 1e-7 * np.ptp(F_off)
    e = ALPHA_EPS
    assert ramp(0.0, e) == 0.0 and ramp(-e, e) == 0.0 and ramp(e, e) == e and ramp(3 * e, e) == 3 * e
    h = 1e-9 * e
    for u in (0.0, e):   # C1 at the joints: one-sided slopes agree (0 at 0, 1 at eps)
        left, right = (ramp(u, e) - ramp(u - h, e)) / h, (ramp(u + h, e) - ramp(u, e)) / h
        assert left == pytest.approx(right, abs=1e-6)


# ------------------------------------------------------------ rod_friction_asymmetric
def test_asymmetric_friction_is_not_an_offset(base):
    """Damper, 13 Hz +-5 mm: the friction the effect adds while the rod
    slides (|v| > 0.05 m/s) grows with the speed, a s2 |v| in both
    directions; a constant offset fitted to it (what a precharge or load-cell
    offset change gives) leaves most of it (a direction-dependent Coulomb
    level, F_c sign(v) + a F_c, would leave almost nothing)."""
    f = 13.0
    ex = Excitation.sine(0.005, f, 2 / f)
    d = _on(base, "rod_friction_asymmetric")
    off, on = simulate(base, ex, "damper"), simulate(d, ex, "damper")
    assert off.ok and on.ok
    last = off.time >= off.time[-1] - 1 / f
    v = off["velocity [m/s]"][last]
    dF = (on["friction force [N]"] - off["friction force [N]"])[last]
    slide = np.abs(v) > 0.05
    resid = dF[slide] - dF[slide].mean()  # the least-squares offset is the mean
    assert np.sqrt(np.mean(resid ** 2)) > 0.3 * np.sqrt(np.mean(dF[slide] ** 2))
    # the added force follows a s2 |v| (film friction), even in v
    a, s2 = d["rod_friction_asymmetric.a"], d["constants.s2"]
    fast = np.abs(v) > 0.8 * np.abs(v).max()
    np.testing.assert_allclose(dF[fast], a * s2 * np.abs(v[fast]), rtol=0.1, atol=0.5)
