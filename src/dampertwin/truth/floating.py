"""The mono tube's floating piston in the truth: a piston WITH mass and an
O-ring's friction between the compression chamber's oil and the gas.

Newton for the piston (mass M, bore area A = the pressure tube's A_B,
position x [m] positive towards the gas, i.e. growing the compression
chamber and shrinking the gas volume):

    M dv/dt = (P_c - P_g) A - F_f,   dx/dt = v.

The O-ring's friction F_f is one Maxwell-slip element (spring K, slip force
F0) with an oil film C_V v, the law of the truth's rod seal (seal.py;
Lampaert, Al-Bender & Swevers, IEEE TAC 48 (2003) 1883; the Bouc-Wen slip
rate of fluid.slip_rate). F0 is the squeeze part F_C L_p of Parker's O-ring
friction (Parker O-Ring Handbook ORD 5700, 2007, sec. 5.6: F = F_C L_p +
F_H A_p); its pressure part F_H A_p is left out: only the small difference
P_c - P_g (F_f / A, some 10 kPa) presses the ring against its groove, < 1 N.
No end stops: the design check (design/architecture.check_gas_volume) keeps
the gas larger than the rod's volume over the compression travel. Gravity
(M g < 1 N against F0 ~ 20 N) is left out.

The model's floating piston is massless and frictionless (model/chambers);
this one is not, on purpose.
"""

from __future__ import annotations

from numba import njit

from .fluid import JIT, slip_rate
from .seal import SLIP_EXPONENT

PARAMS = ("M", "F0", "K", "C_V")
M, F0, K, C_V = range(len(PARAMS))
STATES = (("x_fp", "m", 1e-4, "floating piston position (towards the gas)"),
          ("v_fp", "m/s", 0.1, "floating piston velocity"),
          ("z_fp", "m", 1e-5, "O-ring element deflection"))
X, V, Z = range(len(STATES))


@njit(**JIT)
def floating_piston(y, s, p, o, P_c, P_g, A, dy):
    """Writes the piston's state rates for the compression-chamber pressure
    P_c [Pa], the gas pressure P_g [Pa] and the bore area A [m^2]; returns
    (friction force [N], positive opposing a positive velocity, dissipated
    power [W])."""
    v = y[s + V]
    f = p[o + K] * y[s + Z]
    dz = slip_rate(v, f, p[o + F0], SLIP_EXPONENT)
    F = f + p[o + C_V] * v
    dy[s + X] = v
    dy[s + V] = ((P_c - P_g) * A - F) / p[o + M]
    dy[s + Z] = dz
    return F, f * (v - dz) + p[o + C_V] * v * v
