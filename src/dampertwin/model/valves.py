"""Passive valves (thesis 4.4, eq. 4.19-4.31): 1-DOF mass-spring-damper
discs over a seat, with orifice flow through the opening, bleed and slot.

Four valves: piston rebound shim, piston intake, base compression shim, base
intake. Each is described by one block of the parameter vector (layout
``V_*`` below). Lift x [m] positive opening; p1 upstream, p2 downstream [Pa];
flow Q [m^3/s] positive from p1 to p2.
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter, State, index_enum
from .numerics import power

VALVE_NAMES = ("piston_rebound", "piston_intake", "base_compression", "base_intake")
SHIM_VALVES = ("piston_rebound", "base_compression")  # shim stacks: Dahl friction state


def _g(key, default=None):
    """Value of ``key`` in the valve's design group (``default`` when that
    valve type has no such entry, e.g. no bleed on an intake disc)."""
    if default is None:
        return lambda d, valve: d.group(valve)[key]
    return lambda d, valve: d.group(valve).get(key, default)


# One block of these per valve in the parameter vector (offsets V.*).
VALVE_PARAMETERS = (
    Parameter("DD", "m", _g("D_d"), "disc (outer) diameter"),
    Parameter("DI", "m", _g("D_i"), "inner (clamp / seat) diameter"),
    Parameter("DH", "m", _g("D_h", 0.0), "hole diameter of an intake disc, eq. 4.22"),
    Parameter("CQ", "-", _g("Cq_max"), "discharge coefficient (max of eq. 4.30)"),
    Parameter("LAM", "-", _g("lambda_crit"), "critical flow number, eq. 4.30"),
    Parameter("AB", "m^2", _g("A_bleed", 0.0), "bleed area"),
    Parameter("CQB", "-", _g("Cq_bleed", 0.0), "bleed discharge coefficient"),
    Parameter("AS", "m^2", _g("A_slot"), "slot (series restriction) area"),
    Parameter("CQS", "-", _g("Cq_slot"), "slot discharge coefficient"),
    Parameter("M", "kg", _g("m_v"), "moving mass"),
    Parameter("C", "N s/m", _g("c_v"), "viscous damping"),
    Parameter("SIG", "N/m", _g("sigma0", 0.0), "Dahl stiffness, eq. 4.26"),
    Parameter("FC", "N", _g("F_c", 1.0), "Dahl friction level, eq. 4.26"),
    Parameter("ALPHA", "-", _g("alpha", 1.0), "Dahl exponent, eq. 4.26"),
    Parameter("PRE", "N", _g("F_preload"), "preload F_k(0) (THESIS-ERRATA 17)"),
    Parameter("A", "N", _g("a"), "spring coefficient a, eq. 4.19"),
    Parameter("B", "1/m", _g("b"), "spring exponent b, eq. 4.19"),
    Parameter("CC", "N", _g("c"), "spring coefficient c, eq. 4.19"),
    Parameter("D", "1/m", _g("d"), "spring exponent d, eq. 4.19"),
    Parameter("XV0", "m", _g("x_v0", 1.0), "squeeze-film gap at the seat, eq. 4.25"),
    Parameter("XMAX", "m", lambda d, valve: d.constant("x_max_" + valve), "lift stop"),
    Parameter("SHIM", "-", lambda d, valve: 1.0 if "A_bleed" in d.group(valve) else 0.0,
              "1 for a shim stack (eq. 4.21, 4.27), 0 for an intake disc (eq. 4.22, 4.28)"),
)
V = index_enum("V", [p.name for p in VALVE_PARAMETERS], __name__)
V_SIZE = len(VALVE_PARAMETERS)

# Parameters shared by all valves and orifices.
PARAMETERS = (
    Parameter("P_TR", "Pa", "constants.p_transition", "laminar-turbulent transition of the orifice law (errata 26)"),
    Parameter("SIN_ZETA", "-", lambda d: math.sin(d["constants.zeta"]), "sine of the jet angle zeta, eq. 4.24"),
    Parameter("K_C", "N/m", "constants.k_contact", "seat / stop contact stiffness (errata 27)"),
    Parameter("ZETA_C", "-", "constants.zeta_contact", "contact damping ratio"),
    Parameter("DELTA_C", "m", "constants.delta_contact", "penetration over which contact damping ramps in"),
    Parameter("A_BP", "m^2", "constants.A_bypass", "rebound -> third tube bypass area"),
    Parameter("CQ_BP", "-", "constants.Cq_bypass", "bypass discharge coefficient"),
    Parameter("E_STICTION", "-", "effects.valve_stiction", "switch: squeeze-film stiction, eq. 4.25"),
    Parameter("E_SHIM_FRICTION", "-", "effects.shim_friction", "switch: Dahl friction of shim stacks, eq. 4.26"),
    Parameter("E_JET", "-", "effects.jet_force", "switch: flow momentum force, eq. 4.24"),
    Parameter("E_CQ", "-", "effects.flow_number_cq", "switch: Cq(lambda), eq. 4.30-4.31"),
    Parameter("E_SLOT", "-", "effects.slot_restriction", "switch: slot in series (errata 25)"),
)


VS = index_enum("VS", ["x", "v", "F_dahl"], __name__)  # offsets inside a valve's state block


def valve_states(valve: str, k: int | None = None, dahl: bool | None = None) -> tuple[State, ...]:
    """States of one valve: lift and velocity (eq. 4.20) and, for a shim
    stack, the Dahl force (eq. 4.26), in the order of ``VS``. ``k`` is its
    parameter block (None: the flow bench's valve, block BENCH_VALVE)."""
    def lift(q):
        kk = int(q["BENCH_VALVE"]) if k is None else k
        return seated_lift(q.block("VALVES", kk, V_SIZE), q["K_C"])

    st = (State(f"x_{valve}", "m", 1e-4, lift, f"lift of the {valve} valve (seated at rest)"),
          State(f"v_{valve}", "m/s", 1.0 if k is not None else 1e-1, 0.0, f"velocity of the {valve} valve"))
    if valve in SHIM_VALVES if dahl is None else dahl:
        # scale: the friction level F_c of a shim stack (10-15 N in the baseline), not 1 N (bench/README.md "State scales")
        st += (State(f"F_dahl_{valve}", "N", 10.0, 0.0, f"Dahl friction force of the {valve} valve"),)
    return st


def seated_lift(block, k_c: float) -> float:
    """Lift [m] where a valve rests on its seat with no pressure difference:
    the seat contact balances the preloaded spring (x < 0)."""
    x = -block[V.PRE] / k_c
    for _ in range(50):  # Newton on k_c(-x) - F_k(x) = 0
        r = -k_c * x - stiffness_force(x, block[V.PRE], block[V.A], block[V.B], block[V.CC], block[V.D])
        dk = block[V.A] * block[V.B] * math.exp(block[V.B] * x) + block[V.CC] * block[V.D] * math.exp(block[V.D] * x)
        step = r / (-k_c - dk)
        x -= step
        if abs(step) < 1e-16:
            break
    return x


@njit(cache=True, error_model="numpy")
def regularised_sqrt(dp, p_tr):
    """sign(dp) sqrt|dp| for |dp| >> p_tr, linear (laminar) below the
    transition pressure p_tr: dp / (dp^2 + p_tr^2)^(1/4) (THESIS-ERRATA 26).
    Odd, smooth and monotone."""
    return dp / math.sqrt(math.sqrt(dp * dp + p_tr * p_tr))  # (.)^(1/4) as two square roots: no pow call


@njit(cache=True, error_model="numpy")
def orifice_flow(G, dp, rho, p_tr):
    """Orifice law eq. 4.29, Q = G sqrt(2 dp / rho), with G = Cq A [m^2]."""
    return G * math.sqrt(2.0 / rho) * regularised_sqrt(dp, p_tr)


@njit(cache=True, error_model="numpy")
def discharge_coefficient(cq_max, lam_crit, x, nu, dp, rho):
    """Cq(lambda), eq. 4.30-4.31, with D_hyd = 2x for the slit
    (THESIS-ERRATA 24), so Cq -> 0 as the valve closes."""
    lam = 2.0 * max(x, 0.0) / nu * math.sqrt(2.0 * abs(dp) / rho)
    return cq_max * math.tanh(2.0 * lam / lam_crit)


@njit(cache=True, error_model="numpy")
def stiffness_force(x, F_pre, a, b, c, d):
    """Two-term exponential spring, eq. 4.19, with F_k(0) = F_preload
    (THESIS-ERRATA 17): F_pre + a(e^{bx} - 1) + c(e^{dx} - 1) [N]."""
    return F_pre + a * (math.exp(b * x) - 1.0) + c * (math.exp(d * x) - 1.0)


@njit(cache=True, error_model="numpy")
def shim_pressure_force(dp, D_d, D_i):
    """Net pressure force on a shim stack, eq. 4.21 with the back pressure
    subtracted (THESIS-ERRATA 19): pi/12 (D_d - D_i)(2 D_d + D_i) dp [N]."""
    return math.pi / 12.0 * (D_d - D_i) * (2.0 * D_d + D_i) * dp


@njit(cache=True, error_model="numpy")
def intake_pressure_force(dp, D_d, D_h):
    """Pressure force on an intake disc, eq. 4.22 [N]."""
    return math.pi * dp / 4.0 * (D_d * D_d - D_h * D_h)


@njit(cache=True, error_model="numpy")
def shim_flow_area(x, D_d):
    """Opening area of a shim valve, eq. 4.27 [m^2]."""
    return max(x, 0.0) * math.pi * D_d


@njit(cache=True, error_model="numpy")
def intake_flow_area(x, D_d, D_i):
    """Opening area of an intake valve, eq. 4.28 as printed (errata 20) [m^2]."""
    return max(x, 0.0) * math.pi * (D_d + D_i)


@njit(cache=True, error_model="numpy")
def jet_force(cq, A_f, dp, sin_zeta):
    """Flow momentum force, eq. 4.24, acting to open (THESIS-ERRATA 23) [N];
    ``sin_zeta`` the sine of the jet angle (a packed parameter, computed once)."""
    return 2.0 * cq * cq * A_f * dp * sin_zeta


@njit(cache=True, error_model="numpy")
def stiction_force(x, xdot, mu, x_v0, D_d, D_i):
    """Squeeze-film stiction of an intake disc, eq. 4.25, with X = D_d/D_i > 1
    and mu = rho*nu (THESIS-ERRATA 21). Opposes xdot in both directions [N]."""
    X = D_d / D_i
    X2 = X * X
    X4 = X2 * X2
    bracket = 1.0 - X4 + (1.0 - 2.0 * X2 + X4) / math.log(X)
    gap = max(x, 0.0) + x_v0
    return 3.0 * math.pi * mu / (32.0 * gap * gap * gap) * xdot * D_i ** 4 * bracket


@njit(cache=True, error_model="numpy")
def dahl_rate(F, xdot, sigma0, F_c, alpha):
    """Dahl friction, eq. 4.26, as a rate: dF/dt = sigma0 (1 - F/F_c sgn(xdot))^alpha xdot.
    The exact sgn is kept (THESIS-ERRATA 22): the rate is continuous because it
    is multiplied by xdot, and |F| <= F_c holds."""
    if xdot == 0.0:
        return 0.0
    s = 1.0 if xdot > 0.0 else -1.0
    base = 1.0 - F / F_c * s
    if base <= 0.0:
        return 0.0
    return sigma0 * power(base, alpha) * xdot


@njit(cache=True, error_model="numpy")
def contact_force(x, v, x_max, k_c, c_c, delta):
    """Seat (x < 0) and lift stop (x > x_max) as one-sided penalty contacts
    (THESIS-ERRATA 27). The damping ramps in over ``delta`` of penetration and
    the contact never pulls. Positive = opening direction [N]."""
    f = 0.0
    pen = -x
    if pen > 0.0:
        f += max(0.0, k_c * pen - c_c * min(pen / delta, 1.0) * v)
    pen = x - x_max
    if pen > 0.0:
        f -= max(0.0, k_c * pen + c_c * min(pen / delta, 1.0) * v)
    return f


@njit(cache=True, error_model="numpy", inline="always")
def valve_flow(p, o, x, dp, rho, nu, p_tr, use_cq_lambda, use_slot):
    """Flow through one valve [m^3/s] and the share of dp seen by the disc.

    [opening || bleed] in series with the slot (THESIS-ERRATA 25):
    G1 = Cq A_f + Cq_b A_bleed, G2 = Cq_s A_slot, G = G1 G2 / sqrt(G1^2 + G2^2),
    dp_disc = dp G2^2 / (G1^2 + G2^2). Returns (Q, dp_disc, Cq, A_f)."""
    shim = p[o + V.SHIM] > 0.5
    if shim:
        A_f = shim_flow_area(x, p[o + V.DD])
    else:
        A_f = intake_flow_area(x, p[o + V.DD], p[o + V.DI])
    if use_cq_lambda:
        cq = discharge_coefficient(p[o + V.CQ], p[o + V.LAM], x, nu, dp, rho)
    else:
        cq = p[o + V.CQ]
    G1 = cq * A_f + p[o + V.CQB] * p[o + V.AB]
    if use_slot:
        G2 = p[o + V.CQS] * p[o + V.AS]
        s = G1 * G1 + G2 * G2
        G = G1 * G2 / math.sqrt(s)
        dp_disc = dp * G2 * G2 / s
    else:
        G = G1
        dp_disc = dp
    return orifice_flow(G, dp, rho, p_tr), dp_disc, cq, A_f


@njit(cache=True, error_model="numpy", inline="always")
def valve_acceleration(p, o, x, v, F_dahl, dp_disc, cq, A_f, mu, sin_zeta, k_c, zeta_c, delta,
                       use_jet, use_stiction, use_friction):
    """Equation of motion eq. 4.20: m x'' = -c x' - F_k + F_st + F_dp - F_mu + F_m + F_contact.
    Returns (x'', dF_dahl/dt)."""
    shim = p[o + V.SHIM] > 0.5
    m = p[o + V.M]
    if shim:
        F_dp = shim_pressure_force(dp_disc, p[o + V.DD], p[o + V.DI])
    else:
        F_dp = intake_pressure_force(dp_disc, p[o + V.DD], p[o + V.DH])
    F = F_dp - p[o + V.C] * v - stiffness_force(x, p[o + V.PRE], p[o + V.A], p[o + V.B], p[o + V.CC], p[o + V.D])
    if use_jet:
        F += jet_force(cq, A_f, dp_disc, sin_zeta)
    if use_stiction and not shim:
        F += stiction_force(x, v, mu, p[o + V.XV0], p[o + V.DD], p[o + V.DI])
    dF = 0.0
    if use_friction and shim:
        F -= F_dahl  # friction opposes motion (THESIS-ERRATA 22)
        dF = dahl_rate(F_dahl, v, p[o + V.SIG], p[o + V.FC], p[o + V.ALPHA])
    c_c = 2.0 * zeta_c * math.sqrt(k_c * m)
    F += contact_force(x, v, p[o + V.XMAX], k_c, c_c, delta)
    return F / m, dF


@njit(cache=True, error_model="numpy", inline="always")
def valve(y, o, k, p, p1, p2, dy, nu):
    """Valve k (parameter block k) in the assembled model, its states at
    y[o + VS.*], between upstream p1 and downstream p2 [Pa], oil viscosity
    nu [m^2/s] (p[P.NU] unless oil_thermal): writes its state rates, returns
    the flow p1 -> p2 [m^3/s]."""
    b = _L.P.VALVES + k * V_SIZE
    x = y[o + VS.x]
    v = y[o + VS.v]
    shim = p[b + V.SHIM] > 0.5
    F_dahl = y[o + VS.F_dahl] if shim else 0.0
    rho = p[_L.P.RHO]
    Q, dp_disc, cq, A_f = valve_flow(p, b, x, p1 - p2, rho, nu, p[_L.P.P_TR],
                                     p[_L.P.E_CQ] > 0.5, p[_L.P.E_SLOT] > 0.5)
    a, dF = valve_acceleration(p, b, x, v, F_dahl, dp_disc, cq, A_f, rho * nu, p[_L.P.SIN_ZETA],
                               p[_L.P.K_C], p[_L.P.ZETA_C], p[_L.P.DELTA_C], p[_L.P.E_JET] > 0.5,
                               p[_L.P.E_STICTION] > 0.5, p[_L.P.E_SHIM_FRICTION] > 0.5)
    dy[o + VS.x] = v
    dy[o + VS.v] = a
    if shim:
        dy[o + VS.F_dahl] = dF
    return Q


@njit(cache=True, error_model="numpy", inline="always")
def valve_absent(o, k, p, dy):
    """A valve the architecture lacks (a mono tube's base valves): its states
    at y[o + VS.*] stay at rest; no flow."""
    dy[o + VS.x] = 0.0
    dy[o + VS.v] = 0.0
    if p[_L.P.VALVES + k * V_SIZE + V.SHIM] > 0.5:
        dy[o + VS.F_dahl] = 0.0
    return 0.0


@njit(cache=True, error_model="numpy", inline="always")
def bypass(p, P_r, P_b):
    """Bypass orifice rebound chamber -> third tube [m^3/s] (eq. 4.29)."""
    return orifice_flow(p[_L.P.CQ_BP] * p[_L.P.A_BP], P_r - P_b, p[_L.P.RHO], p[_L.P.P_TR])


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
