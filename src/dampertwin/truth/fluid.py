"""Oil, orifices and small regularised elements of the truth.

Sources: Murnaghan, PNAS 30 (1944) 244 (equation of state with a linear
pressure dependence of the tangent modulus); ASTM D341 / Walther (1931)
viscosity-temperature law; Idelchik, Handbook of Hydraulic Resistance (1986)
and Merritt, Hydraulic Control Systems (1967) ch. 3 for laminar + turbulent
losses in series; Hunt & Crossley, J. Appl. Mech. 42 (1975) 440 for
contact. SI units; pressures absolute.
"""

from __future__ import annotations

import math

from numba import njit

JIT = dict(cache=True, error_model="numpy")

# the oil's parameter block (offsets inside it)
PARAMS = ("RHO0", "K0", "K1", "P_REF", "BETA_T", "T0", "WALTHER_A", "WALTHER_B", "P_V", "P_ATM")
RHO0, K0, K1, P_REF, BETA_T, T0, WALTHER_A, WALTHER_B, P_V, P_ATM = range(len(PARAMS))
P_FLOOR_EPS = 2000.0  # [Pa] rounding of the pressure floor at the vapour pressure (gas law)


@njit(**JIT)
def ramp(x, eps):
    """Smooth positive part, the softplus eps ln(1 + e^(x/eps)) in an
    overflow-free form; -> max(x, 0) for |x| >> eps."""
    r = x / eps
    return eps * (max(r, 0.0) + math.log1p(math.exp(-abs(r))))


@njit(**JIT)
def ramp_slope(x, eps):
    """d ramp / dx: the logistic function of x / eps."""
    e = math.exp(-abs(x / eps))
    return 1.0 / (1.0 + e) if x >= 0.0 else e / (1.0 + e)


@njit(**JIT)
def density(P, T, p, o):
    """Oil density [kg/m^3]: Murnaghan rho0 (1 + K1 (P - P_ref)/K0)^(1/K1), times
    the thermal expansion exp(-beta (T - T0))."""
    base = 1.0 + p[o + K1] * (P - p[o + P_REF]) / p[o + K0]
    return p[o + RHO0] * base ** (1.0 / p[o + K1]) * math.exp(-p[o + BETA_T] * (T - p[o + T0]))


@njit(**JIT)
def modulus(P, p, o):
    """Tangent bulk modulus of the liquid K0 + K1 (P - P_ref) [Pa] (Murnaghan)."""
    return p[o + K0] + p[o + K1] * (P - p[o + P_REF])


@njit(**JIT)
def viscosity(T, p, o):
    """Kinematic viscosity [m^2/s], Walther: log10 log10(nu_cSt + 0.7) = A - B log10 T."""
    z = 10.0 ** (10.0 ** (p[o + WALTHER_A] - p[o + WALTHER_B] * math.log10(T)))
    return (z - 0.7) * 1e-6


def walther_coefficients(nu: float, T: float, slope: float) -> tuple[float, float]:
    """(A, B) of the Walther law through nu [m^2/s] at T [K] with
    d ln(nu)/dT = -slope [1/K] there."""
    z = nu * 1e6 + 0.7
    B = slope * T * nu * 1e6 / (z * math.log(z))
    return math.log10(math.log10(z)) + B * math.log10(T), B


@njit(**JIT)
def throttle(dp, R_lam, CdA, rho):
    """Flow [m^3/s] through a restriction with laminar and turbulent losses in
    series, dp = R_lam Q + rho Q|Q| / (2 CdA^2): the root
    Q = 2 dp / (R_lam + sqrt(R_lam^2 + 2 rho |dp| / CdA^2)). Odd in dp,
    smooth, zero when CdA = 0 (R_lam > 0 required)."""
    return 2.0 * dp / (R_lam + math.sqrt(R_lam * R_lam + 2.0 * rho * abs(dp) / (CdA * CdA + 1e-300)))


@njit(**JIT)
def radial_gap_resistance(mu, r_in, r_out, h):
    """Laminar resistance of radial flow between parallel discs over a land
    r_in..r_out at gap h: 6 mu ln(r_out / r_in) / (pi h^3) [Pa s/m^3]
    (Merritt 1967 eq. 3-41)."""
    return 6.0 * mu * math.log(r_out / r_in) / (math.pi * h * h * h)


@njit(**JIT)
def hunt_crossley(delta, rate, k, lam, eps):
    """Contact force [N] >= 0 of a penetration delta [m] growing at rate
    [m/s]: k d^1.5 (1 + lam rate) (Hunt & Crossley 1975), d the rounded
    positive part of delta; and the power it dissipates [W]."""
    d = ramp(delta, eps)
    elastic = k * d * math.sqrt(d)
    factor = ramp(1.0 + lam * rate, 0.05)
    return elastic * factor, elastic * (factor - 1.0) * rate


@njit(**JIT)
def slip_rate(v, F, W, n):
    """Rate of a Maxwell-slip element's spring deflection [m/s]: sticks
    (rate v) below its slip force W, slides when |F| reaches W, as the
    Bouc-Wen law with beta = gamma = 1/2 and exponent n: v - |F/W|^n (v +
    |v| sign F) / 2 (Wen, J. Eng. Mech. 102 (1976) 249; Lampaert, Al-Bender
    & Swevers, IEEE TAC 48 (2003) 1883 for the generalised Maxwell-slip
    structure)."""
    phi = abs(F / W)
    s = 1.0 if F >= 0.0 else -1.0
    return v - 0.5 * phi ** n * (v + abs(v) * s)


def lame_compliance(r_i: float, r_o: float, E: float, nu: float) -> float:
    """Volumetric compliance dV/(V dP) [1/Pa] of a thick-walled open-ended tube
    under internal pressure: 2 u/r_i with u = P r_i / E ((r_o^2 + r_i^2) /
    (r_o^2 - r_i^2) + nu) (Lame; Timoshenko, Strength of Materials II,
    1956, 2.41)."""
    return 2.0 / E * ((r_o ** 2 + r_i ** 2) / (r_o ** 2 - r_i ** 2) + nu)


def land_area(r_in: float, r_out: float) -> float:
    """Pressure-loaded area [m^2] of a closed seat: the inner disc plus the
    land r_in..r_out carrying the laminar leakage's logarithmic pressure
    profile p(r) = dp ln(r_out/r) / ln(r_out/r_in) (finite seat width)."""
    L = math.log(r_out / r_in)
    land = 2.0 * math.pi / L * (r_out ** 2 / 4.0 - r_in ** 2 / 2.0 * L - r_in ** 2 / 4.0)
    return math.pi * r_in ** 2 + land
