"""Assembled right-hand sides of the configurations (thesis ch. 4).

- ``valve``  (flow bench): one valve between an upstream volume fed with a
  prescribed flow and a constant back pressure.
- ``damper`` (rod fixed, eq. 4.1): tube displacement u(t) prescribed, the
  stroke is s = u; the output force is the rod force.
- ``module`` (eq. 4.4): tube displacement prescribed at the lower mount, the
  rod is a mass on the top mount; s = u - x_rod (THESIS-ERRATA 5).
- ``topmount``: the top mount alone, deflection prescribed (thesis 6.4).

Each configuration is one compiled right-hand side ``rhs_<cfg>(t, y, p, ex,
aux, dy, out)`` with the solver's signature (``solver.rhs_signature``): it
fills the state derivative ``dy`` and the output channels ``out``
(layout.OUTPUTS) for one (t, y). ``aux`` is the active-valve map
(``active_valve.pack_map``). Everything in SI. They compile at first use,
not at import (``dampertwin.jit``).

This file is the hub: the chamber volume balances (eq. 4.9-4.12) that join
the submodels' flows, and the rod force (eq. 4.1). Each submodel reads its
own parameters (``p[P.<name>]``) and states (at the offset of its block,
``SB.<block>``) and writes its own state rates, so adding a parameter or a
state to a submodel does not touch this file.

The effects the thesis lacks (docs "Effect library") hook in here, each a
call into its own file that returns its input unchanged when switched off.
The effects with states (active_valve_lag, valve_friction_current, oil_thermal, aeration,
fixture_resonance, active_valve_driver, gas_release) run only
in the extended configurations ``rhs_damper_x`` / ``rhs_module_x`` (layout.variant), whose
effect states follow the damper / module states.
"""

from __future__ import annotations

from numba import njit, types

from ..jit import lazy_njit
from ..solver import rhs_signature
from .active_valve import active_flow, commanded_current, opening_flow
from .active_valve_driver import effective_current
from .active_valve_lag import opening_pressure
from .aeration import aeration
from .bench import upstream_modulus, upstream_pressure_rate
from .fixture_resonance import load_cell
from .gas_release import gas_release
from .chambers import MONO_TUBE, TWIN_TUBE, chamber_volumes, floating_piston, moduli, pressure_rate, rod_force
from .fluid import gas_spring_pressure
from .inputs import hermite
from .layout import (BB, CFG_DAMPER, CFG_DAMPER_X, CFG_MODULE, CFG_MODULE_X, CFG_TOPMOUNT, CFG_VALVE, EB_DAMPER,
                     EB_MODULE, EX, O, SB, TB, P, S)
from .oil_thermal import expansion, gas_temperature_factor, heat, oil_state, oil_temperature, oil_viscosity
from .piston_leakage import leakage
from .rod import motion, rod_position, stroke
from .rod_friction import friction
from .top_mount import mount
from .valve_friction_current import spool_pressure
from .valves import bypass, valve, valve_absent

SIGNATURE = rhs_signature()


@njit(cache=True, error_model="numpy", inline="always")
def excitation_at(t, p, ex):
    """Prescribed input and its rate at t (inputs.hermite on the test's grid)."""
    return hermite(t, p[P.EX_T0], p[P.EX_DT], ex)


# One compiled body for the four configurations (``module``, ``extended`` are
# run-time flags, not literals): the four right-hand sides below call it. With
# the body inlined into each (literal flags), a cold cache compiled it four
# times (~50 s CPU) for ~4 % less run time (bench/README, "Compile time").
@lazy_njit(types.void(*SIGNATURE.args, types.boolean, types.boolean), cache=True, error_model="numpy", _nrt=False)
def _damper(t, y, p, ex, aux, dy, out, module, extended):
    """Damper (rod fixed, eq. 4.1: stroke s = u) or module (eq. 4.4: the rod
    on the top mount, s = u - x_rod); ``extended``: with the effect states."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    u, du = excitation_at(t, p, ex)
    if module:
        s, sd = stroke(y, SB.rod, u, du)
    else:
        s = u
        sd = du
    A_r = p[P.A_R]
    A_b = p[P.A_B]
    P_r = y[S.P_r]
    P_c = y[S.P_c]
    P_b = y[S.P_b]
    oe = EB_MODULE if module else EB_DAMPER  # effect states (extended configurations)
    # architecture (design/architecture.py): the passive ones lack the third tube and the active valve,
    # the mono tube also the base valves (its gas sits behind a floating piston)
    mono = p[P.ARCH] == MONO_TUBE
    passive = mono or p[P.ARCH] == TWIN_TUBE
    P_res = gas_spring_pressure(p[P.P0], p[P.V_G0], y[S.V_g], p[P.GAMMA])
    K_oil = p[P.K_OIL]
    T_oil = p[P.TEMP]
    if extended:  # oil_thermal: the reserve gas at the oil temperature, the oil's modulus at it
        P_res *= gas_temperature_factor(y, oe + EX.T_oil, p)
        K_oil, T_oil = oil_state(y, oe + EX.T_oil, p)
    if mono:  # the floating piston holds the compression chamber at the gas pressure (chambers.floating_piston)
        P_c = P_res

    # oil viscosity, at the oil temperature with the effect oil_thermal
    nu = p[P.NU]
    if extended:
        nu = oil_viscosity(y, oe + EX.T_oil, p)

    # valves (eq. 4.19-4.31): 0 piston rebound r->c, 1 piston intake c->r,
    # 2 base compression c->res, 3 base intake res->c
    Q0 = valve(y, SB.piston_rebound, 0, p, P_r, P_c, dy, nu)
    Q1 = valve(y, SB.piston_intake, 1, p, P_c, P_r, dy, nu)
    if mono:
        Q2 = valve_absent(SB.base_compression, 2, p, dy)
        Q3 = valve_absent(SB.base_intake, 3, p, dy)
    else:
        Q2 = valve(y, SB.base_compression, 2, p, P_c, P_res, dy, nu)
        Q3 = valve(y, SB.base_intake, 3, p, P_res, P_c, dy, nu)
    Q_p = Q0 - Q1 + leakage(p, P_r, P_c, p[P.NU] / nu)  # rebound -> compression (THESIS-ERRATA 7)
    Q_bv = Q2 - Q3  # compression -> reserve
    Q_bp = 0.0
    Q_a = 0.0
    if not passive:
        Q_bp = bypass(p, P_r, P_b)
        # active valve: static map (4.4); the effects spool friction and lag move its opening
        # (the map's opening at p_o, under the actual drop: active_valve.opening_flow)
        dp_a = P_b - P_res
        I_a = commanded_current(p)
        if extended:  # active_valve_driver: the valve sees the coil's effective current (the command when off)
            I_a = effective_current(t, y, oe + EX.i_coil, p, dy)
        Q_a = active_flow(p, aux, dp_a, I_a)
        if extended:
            p_o = spool_pressure(y, oe + EX.p_spool, p, dp_a, dy, I_a)
            p_o = opening_pressure(y, oe + EX.p_open, p, p_o, dy)
            Q_a = opening_flow(p, aux, p_o, dp_a, Q_a, I_a)
    elif extended:  # a passive damper has no active valve: its effect states stay at their initial values
        dy[oe + EX.i_coil] = 0.0
        dy[oe + EX.i_eff] = 0.0
        dy[oe + EX.p_spool] = 0.0
        dy[oe + EX.p_open] = 0.0

    # rod friction (eq. 4.38-4.41) and rod force (eq. 4.1); oil_thermal heats with F_d s'
    F_mu = friction(y, SB.rod_friction, p, sd, dy, P_r)
    F_d = rod_force(P_r, P_c, A_r, A_b, p[P.P_ATM], F_mu)
    dT = 0.0
    if extended:
        dT = heat(y, oe + EX.T_oil, p, F_d * sd, dy)  # dissipated power F_d s' [W]

    # compliance (eq. 4.13-4.18) and chambers (eq. 4.5-4.12)
    # the pressure tube's outside: the reserve, or the atmosphere around a mono tube
    K_r, K_c, K_b = moduli(p, P_r, P_c, P_b, p[P.P_ATM] if mono else P_res, K_oil, T_oil)
    V_r, V_c = chamber_volumes(s, A_r, A_b, p[P.L_R0], p[P.L_C0])
    if mono:  # the floating piston has moved by the gas volume's change
        V_c += p[P.V_G0] - y[S.V_g]
    dV_r = -A_r * sd
    dV_c = A_b * sd
    dV_b = 0.0
    if extended:  # gas_release: eq. 4.14's gas share a state per chamber (frozen modulus, released-gas source)
        K_r, K_c, K_b, S_r, S_c, S_b = gas_release(y, oe + EX.theta_r, p, K_r, K_c, K_b, P_r, P_c, P_b, P_res,
                                                   K_oil, T_oil, V_r, V_c, dy)
        dV_r -= S_r
        dV_c -= S_c
        dV_b -= S_b
    if extended:  # aeration: free air in the compression chamber, released / dissolved at finite rates
        K_c, dV_air = aeration(y, oe + EX.V_air, p, K_c, P_c, V_c, dy)
        dV_c -= dV_air
    if extended:  # oil_thermal: the oil's expansion as a volume source (0 when off)
        e_r, e_c, e_b = expansion(p, V_r, V_c, p[P.V_B], dT)
        dV_r -= e_r
        dV_c -= e_c
        dV_b -= e_b
    dy[S.P_r] = pressure_rate(K_r, V_r, dV_r, Q_p + Q_bp)
    if mono:
        dy[S.P_c], dy[S.V_g] = floating_piston(K_c, V_c, dV_c, -Q_p, P_res, y[S.V_g], p[P.GAMMA],
                                               P_res * dT / T_oil if extended else 0.0)
    else:
        dy[S.P_c] = pressure_rate(K_c, V_c, dV_c, -Q_p + Q_bv)
        dy[S.V_g] = -(Q_bv + Q_a)  # reserve gas (THESIS-ERRATA 8)
    if passive:  # no third tube: its pressure state stays at the precharge
        dy[S.P_b] = 0.0
    else:
        dy[S.P_b] = pressure_rate(K_b, p[P.V_B], dV_b, Q_a - Q_bp)

    F_tm = 0.0
    a_rod = 0.0
    if module:
        # top mount (eq. 4.32-4.37) and rod equation of motion (eq. 4.4)
        x_rod, v_rod = rod_position(y, SB.rod)
        F_tm = mount(y, SB.top_mount, p, x_rod, v_rod, dy)
        a_rod = motion(y, SB.rod, p, F_d, F_tm, dy)

    out[O.U] = u
    out[O.V] = du
    out[O.S] = s
    out[O.F_D] = F_d
    out[O.F_TM] = F_tm
    if extended:  # fixture_resonance: the load cell's reading of the force on the fixture (F_d or F_tm when off)
        F_lc = load_cell(y, oe + EX.F_cell, p, F_tm if module else F_d, dy)
        if module:
            out[O.F_TM] = F_lc
        else:
            out[O.F_D] = F_lc
    out[O.A_ROD] = -a_rod  # reported positive up (THESIS-ERRATA 5)
    out[O.F_MU] = F_mu
    out[O.P_R] = P_r
    out[O.P_C] = P_c
    out[O.P_B] = P_b
    out[O.P_RES] = P_res
    out[O.X0] = y[SB.piston_rebound]
    out[O.X1] = y[SB.piston_intake]
    out[O.X2] = y[SB.base_compression]
    out[O.X3] = y[SB.base_intake]
    out[O.Q0] = Q0
    out[O.Q1] = Q1
    out[O.Q2] = Q2
    out[O.Q3] = Q3
    out[O.Q_BP] = Q_bp
    out[O.Q_A] = Q_a
    out[O.ST_R] = V_r / K_r * dy[S.P_r]
    out[O.ST_C] = V_c / K_c * dy[S.P_c]
    out[O.ST_B] = p[P.V_B] / K_b * dy[S.P_b]
    out[O.DVG] = dy[S.V_g]
    out[O.T_OIL] = oil_temperature(y, oe + EX.T_oil, p) if extended else p[P.TEMP]


@lazy_njit(SIGNATURE, cache=True, error_model="numpy", _nrt=False)
def rhs_damper(t, y, p, ex, aux, dy, out):
    """Damper configuration: tube displacement prescribed, rod fixed."""
    _damper(t, y, p, ex, aux, dy, out, False, False)


@lazy_njit(SIGNATURE, cache=True, error_model="numpy", _nrt=False)
def rhs_module(t, y, p, ex, aux, dy, out):
    """Module configuration: the rod on the top mount (eq. 4.4)."""
    _damper(t, y, p, ex, aux, dy, out, True, False)


@lazy_njit(SIGNATURE, cache=True, error_model="numpy", _nrt=False)
def rhs_damper_x(t, y, p, ex, aux, dy, out):
    """Damper configuration with the effect states (layout.CFG_DAMPER_X)."""
    _damper(t, y, p, ex, aux, dy, out, False, True)


@lazy_njit(SIGNATURE, cache=True, error_model="numpy", _nrt=False)
def rhs_module_x(t, y, p, ex, aux, dy, out):
    """Module configuration with the effect states (layout.CFG_MODULE_X)."""
    _damper(t, y, p, ex, aux, dy, out, True, True)


@lazy_njit(SIGNATURE, cache=True, error_model="numpy", _nrt=False)
def rhs_valve(t, y, p, ex, aux, dy, out):
    """Flow bench (thesis 2.7.2, 6.2.1): prescribed flow Q_in into an
    upstream volume of gas-free oil, one valve to a constant back pressure."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    for i in range(dy.shape[0]):
        dy[i] = 0.0
    Q_in, dQ = excitation_at(t, p, ex)
    P_up = y[BB.bench]
    P_dn = p[P.BENCH_P_DOWN]
    Q = valve(y, BB.valve, int(p[P.BENCH_VALVE]), p, P_up, P_dn, dy, p[P.NU])
    dy[BB.bench] = upstream_pressure_rate(upstream_modulus(p, P_up), p[P.BENCH_V], Q, Q_in)
    out[O.U] = Q_in
    out[O.V] = dQ
    out[O.P_R] = P_up
    out[O.P_C] = P_dn
    out[O.X0] = y[BB.valve]
    out[O.Q0] = Q


@lazy_njit(SIGNATURE, cache=True, error_model="numpy", _nrt=False)
def rhs_topmount(t, y, p, ex, aux, dy, out):
    """Top-mount test bench (thesis 6.4): deflection X(t) prescribed, force out."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    X, Xd = excitation_at(t, p, ex)
    out[O.U] = X
    out[O.V] = Xd
    out[O.F_TM] = mount(y, TB.top_mount, p, X, Xd, dy)


RHS = {"valve": rhs_valve, "damper": rhs_damper, "module": rhs_module, "topmount": rhs_topmount}
# by configuration code, the extended variants included (layout.variant)
RHS_BY_CFG = {CFG_VALVE: rhs_valve, CFG_DAMPER: rhs_damper, CFG_MODULE: rhs_module, CFG_TOPMOUNT: rhs_topmount,
              CFG_DAMPER_X: rhs_damper_x, CFG_MODULE_X: rhs_module_x}
