"""Submodels against analytic cases and independent computations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from dampertwin.design import load
from dampertwin.model import fluid, rod_friction, valves
from dampertwin.model import layout as L
from dampertwin.model.active_valve import active_valve_flow
from dampertwin.model.chambers import rod_force
from dampertwin.model.params import pack
from dampertwin.model.valves import V_SIZE

from conftest import BASELINE

OIL = dict(K_oil=7.7e8, chi=0.0035, P_sat=1.0e6, P_vap=2000.0, P_ref=101325.0, T=303.15, T_ref=293.15, Gamma=1.4)


def K(P, **kw):
    o = {**OIL, **kw}
    return fluid.emulsion_bulk_modulus(P, o["K_oil"], o["chi"], o["P_sat"], o["P_vap"], o["P_ref"], o["T"],
                                       o["T_ref"], o["Gamma"])


# ------------------------------------------------------------ fluid
def test_emulsion_equals_oil_above_saturation():
    for P in (1.0e6 + fluid.SAT_BLEND + 1.0, 2e6, 8e6):
        assert K(P) == pytest.approx(OIL["K_oil"], rel=1e-12)


def test_reg1_blend_equals_the_sharp_law_outside_its_bands_and_removes_the_jump():
    """REG-1: the clipped gas share of eq. 4.14 is blended over +-SAT_BLEND
    around P_vap and P_sat; outside those bands theta is exactly the sharp
    law; across P_sat the modulus no longer jumps (the sharp law jumps by
    ~35 % of K_oil within 1 Pa)."""
    w = fluid.SAT_BLEND
    assert w > 0
    P_sat, P_vap = OIL["P_sat"], OIL["P_vap"]
    for P in np.concatenate([np.linspace(P_vap + w + 1, P_sat - w - 1, 50), np.linspace(P_sat + w + 1, 3e6, 20)]):
        assert fluid.gas_fraction(P, P_sat, P_vap) == fluid.gas_fraction(P, P_sat, P_vap, 0.0)
    sharp = [fluid.gas_fraction(P, P_sat, P_vap, 0.0)[1] for P in (P_sat - 0.5, P_sat + 0.5)]
    assert sharp[0] != sharp[1]  # the kink being regularised
    Ps = np.linspace(P_sat - 2 * w, P_sat + 2 * w, 2001)
    ks = np.array([K(P) for P in Ps])
    assert np.max(np.abs(np.diff(ks))) < 0.01 * OIL["K_oil"]  # continuous: no step between neighbours 100 Pa apart
    th = np.array([fluid.gas_fraction(P, P_sat, P_vap)[0] for P in Ps])
    assert np.all(np.diff(th) <= 0) and th.min() >= 0 and th.max() <= 1


def test_emulsion_modulus_falls_with_gas_content():
    for P in (2e5, 5e5, 9e5):
        ks = [K(P, chi=c) for c in (0.0, 0.001, 0.0035, 0.01, 0.05)]
        assert all(a > b for a, b in zip(ks, ks[1:])), ks


def test_emulsion_modulus_is_rho_dP_drho_of_density_law():
    """K of eq. 4.16 equals rho dP/drho of eq. 4.15 by central differences
    (THESIS-ERRATA 11: full derivative incl. the dissolution term)."""
    o = OIL
    for P in (1.5e5, 4e5, 7e5, 3e6):
        rho = lambda q: fluid.emulsion_density(q, 850.0, 1.16, o["K_oil"], o["chi"], o["P_sat"], o["P_vap"],
                                               o["P_ref"], o["T"], o["T_ref"], o["Gamma"])
        h = P * 1e-6
        k_fd = rho(P) * 2 * h / (rho(P + h) - rho(P - h))
        assert K(P) == pytest.approx(k_fd, rel=1e-5)


def test_wall_compliance_equals_lame():
    """psi of eq. 4.17 (Lame form) from an independent route: Lame stresses at
    the bore of a closed thick tube, then Hooke's law for the hoop strain:
    psi = 2 eps_theta / p."""
    E, nu, ri, ro, p = 2.1e11, 0.3, 0.020, 0.02125, 1e6
    A = p * ri**2 / (ro**2 - ri**2)
    sig_r = A * (1 - ro**2 / ri**2)  # = -p at the bore
    sig_t = A * (1 + ro**2 / ri**2)
    sig_z = A  # closed ends
    assert sig_r == pytest.approx(-p)
    eps_t = (sig_t - nu * (sig_r + sig_z)) / E
    assert fluid.wall_compliance(E, nu, ri, ro) == pytest.approx(2 * eps_t / p, rel=1e-12)
    # the printed eq. 4.17 differs (THESIS-ERRATA 14): ~15 % larger for this tube
    lit = fluid.wall_compliance_literal(E, nu, ri, ro)
    assert lit / fluid.wall_compliance(E, nu, ri, ro) == pytest.approx(1.15, abs=0.02)


def test_gas_spring_is_polytropic():
    assert fluid.gas_spring_pressure(4e5, 8e-5, 4e-5, 1.4) == pytest.approx(4e5 * 2**1.4)


# ------------------------------------------------------------ orifice / valves
@settings(max_examples=200, deadline=None)
@given(st.floats(-2e7, 2e7, allow_nan=False), st.floats(1e-9, 1e-4))
def test_orifice_flow_odd_and_monotone(dp, G):
    q = valves.orifice_flow(G, dp, 850.0, 4000.0)
    assert valves.orifice_flow(G, -dp, 850.0, 4000.0) == -q
    assert valves.orifice_flow(G, dp + abs(dp) * 1e-3 + 1.0, 850.0, 4000.0) > q


def test_orifice_flow_turbulent_limit_and_laminar_core():
    G, rho, ptr = 1e-6, 850.0, 4000.0
    dp = 5e6
    assert valves.orifice_flow(G, dp, rho, ptr) == pytest.approx(G * math.sqrt(2 * dp / rho), rel=1e-6)
    # linear near zero: Q(dp)/dp constant for dp << p_tr
    assert valves.orifice_flow(G, 1.0, rho, ptr) / 1.0 == pytest.approx(valves.orifice_flow(G, 2.0, rho, ptr) / 2.0,
                                                                       rel=1e-6)


@pytest.fixture(scope="module")
def p_base():
    return pack(load(BASELINE), 1.6)


def test_closed_valve_passes_only_bleed(p_base):
    p = p_base
    rho, nu, ptr = p[L.P.RHO], p[L.P.NU], p[L.P.P_TR]
    for k in range(4):
        o = L.P.VALVES + k * V_SIZE
        for dp in (-5e5, 2e5, 3e6):
            q, _, _, A_f = valves.valve_flow(p, o, -1e-6, dp, rho, nu, ptr, True, False)
            assert A_f == 0.0
            bleed = p[o + valves.V.CQB] * p[o + valves.V.AB]
            assert q == pytest.approx(valves.orifice_flow(bleed, dp, rho, ptr), rel=1e-12)
            if k in (1, 3):  # intake valves have no bleed: a closed intake passes nothing
                assert q == 0.0
            else:
                assert q != 0.0


def test_valve_flow_rises_with_lift(p_base):
    p = p_base
    o = L.P.VALVES
    qs = [valves.valve_flow(p, o, x, 2e6, p[L.P.RHO], p[L.P.NU], p[L.P.P_TR], True, True)[0]
          for x in (0.0, 1e-5, 5e-5, 2e-4)]
    assert all(a < b for a, b in zip(qs, qs[1:]))


def test_shim_pressure_force_has_no_net_force_at_equal_pressures():
    """THESIS-ERRATA 19: the resolved eq. 4.21 is proportional to p1 - p2."""
    assert valves.shim_pressure_force(0.0, 0.026, 0.018) == 0.0
    f = valves.shim_pressure_force(1e5, 0.026, 0.018)
    printed = math.pi / 12 * (0.026 - 0.018) * (0.026 * (2 * 2e5 + 1e5) + 0.018 * (2e5 + 2 * 1e5))
    back = 1e5 * math.pi / 4 * (0.026**2 - 0.018**2)
    assert f == pytest.approx(printed - back, rel=1e-12)


def test_stiffness_preload_sign():
    """THESIS-ERRATA 17: F_k(0) = F_preload, spring force grows with lift."""
    assert valves.stiffness_force(0.0, 80.0, 250.0, 4000.0, -150.0, -15000.0) == 80.0
    assert valves.stiffness_force(1e-4, 80.0, 250.0, 4000.0, -150.0, -15000.0) > 80.0


def test_stiction_opposes_motion():
    for xd in (-0.1, 0.1):
        f = valves.stiction_force(1e-5, xd, 0.0102, 2.5e-5, 0.028, 0.022)
        assert f * xd < 0


def test_contact_never_pulls():
    kc, cc, dl = 5e7, 300.0, 1e-6
    # leaving the seat fast: damping would pull, contact force clipped at 0
    assert valves.contact_force(-1e-7, 10.0, 1e-3, kc, cc, dl) == 0.0
    assert valves.contact_force(-1e-6, 0.0, 1e-3, kc, cc, dl) == pytest.approx(50.0)
    assert valves.contact_force(1.001e-3, 0.0, 1e-3, kc, cc, dl) < 0
    assert valves.contact_force(5e-4, 3.0, 1e-3, kc, cc, dl) == 0.0


def test_dahl_loop_bounded_and_closed():
    """Eq. 4.26 under periodic motion: |F| <= F_c, loop closes cycle to cycle,
    friction dissipates (positive loop area)."""
    sigma0, Fc, alpha, A, w = 5e6, 15.0, 1.0, 2e-5, 2 * math.pi * 10

    def rhs(t, y):
        return [valves.dahl_rate(y[0], A * w * math.cos(w * t), sigma0, Fc, alpha)]

    T = 2 * math.pi / w
    t = np.linspace(0, 4 * T, 4001)
    sol = solve_ivp(rhs, (0, 4 * T), [0.0], t_eval=t, rtol=1e-10, atol=1e-10, max_step=T / 400)
    F = sol.y[0]
    assert np.max(np.abs(F)) <= Fc * (1 + 1e-9)
    n = 1000
    assert np.max(np.abs(F[2 * n:3 * n] - F[3 * n:4 * n])) < 1e-4 * Fc
    x = A * np.sin(w * t[3 * n:])
    assert np.trapezoid(F[3 * n:], x) > 0


# ------------------------------------------------------------ rod friction
@pytest.mark.parametrize("v", [-0.5, -0.02, -0.004, 0.001, 0.01, 0.3])
def test_lugre_steady_state_is_stribeck_curve(v):
    kb, Fc, Fs, s2, cc, vd, a_s, al = 2e6, 60.0, 80.0, 50.0, 500.0, 1e-3, 0.01, 2.0
    tau = Fs / (kb * abs(v))  # bristle settling time
    sol = solve_ivp(lambda t, z: [rod_friction.lugre(z[0], v, kb, Fc, Fs, s2, cc, vd, a_s, al)[0]],
                    (0, 30 * tau), [0.0], method="LSODA", rtol=1e-10, atol=1e-14)
    F = rod_friction.lugre(sol.y[0, -1], v, kb, Fc, Fs, s2, cc, vd, a_s, al)[1]
    g = Fc + (Fs - Fc) * math.exp(-((abs(v) / a_s) ** al))
    assert F == pytest.approx(math.copysign(g, v) + s2 * v, rel=1e-6)


# ------------------------------------------------------------ active valve, rod force
def test_active_valve_interpolates_map_and_is_odd():
    d = load(BASELINE)
    m = d.pq_map
    for i, I in enumerate(m.currents):
        for j, dp in enumerate(m.dps):
            assert active_valve_flow(I, dp, m.currents, m.dps, m.flow) == pytest.approx(m.flow[i, j])
            assert active_valve_flow(I, -dp, m.currents, m.dps, m.flow) == pytest.approx(-m.flow[i, j])
    # bilinear midpoint
    q = active_valve_flow(0.5 * (m.currents[0] + m.currents[1]), 0.5 * (m.dps[3] + m.dps[4]), m.currents, m.dps, m.flow)
    assert q == pytest.approx(m.flow[0:2, 3:5].mean())
    # clamped outside the grid
    assert active_valve_flow(5.0, 1e5, m.currents, m.dps, m.flow) == active_valve_flow(m.currents[-1], 1e5, m.currents, m.dps, m.flow)


def test_rod_force_free_body():
    """THESIS-ERRATA 1: a pressure rise in the rebound chamber alone gives a
    rebound (tension) force equal to dP times the annulus area."""
    D_PT, D_R = 0.032, 0.020
    A_r = math.pi * (D_PT**2 - D_R**2) / 4
    A_b = math.pi * D_PT**2 / 4
    base = rod_force(4e5, 4e5, A_r, A_b, 101325.0, 0.0)
    assert base == pytest.approx(-(4e5 - 101325.0) * math.pi * D_R**2 / 4)  # static gas force pushes out
    assert rod_force(5e5, 4e5, A_r, A_b, 101325.0, 0.0) - base == pytest.approx(1e5 * A_r)
    assert rod_force(4e5, 5e5, A_r, A_b, 101325.0, 0.0) - base == pytest.approx(-1e5 * A_b)


def test_piston_leakage_conductance_is_laminar_annulus(p_base):
    """Poiseuille flow in a narrow annular gap: Q = pi D h^3 dp / (12 mu L)."""
    d = load(BASELINE)
    mu = d["oil.rho_oil"] * d["oil.nu"]
    G = math.pi * d["geometry.D_PT"] * d["piston_leakage.gap"] ** 3 / (12 * mu * d["piston_leakage.length"])
    assert p_base[L.P.G_LEAK] == pytest.approx(G, rel=1e-12)
    assert p_base[L.P.E_LEAK] == 0.0  # the thesis model has no leakage: off in the baseline


def test_power_shortcuts_agree_with_pow():
    """numerics.power: x ** a, with a = 1, 2, 1/2 as exact cheap operations
    (within one ulp of libm's pow) and any other exponent unchanged."""
    from dampertwin.model.numerics import power

    rng = np.random.default_rng(3)
    for x in np.concatenate([[0.0, 1.0], 10.0 ** rng.uniform(-8, 6, 200)]):
        for a in (1.0, 2.0, 0.5, 0.8, 1.4, 3.0):
            assert abs(power(x, a) - x ** a) <= np.spacing(x ** a), (x, a)
        assert power(x, 0.8) == x ** 0.8
