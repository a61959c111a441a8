"""Chamber volumes of the truth's passive architectures (design key
``architecture:``): the twin tube and the mono tube.

Twin tube (Dixon, The Shock Absorber Handbook, 2nd ed. 2007, sec. 1.4): the
pressure tube sits in the reserve tube; no third tube, no active valve. The
pressure tube's wall stretches with P_r - P_W and P_c - P_W (the reserve
outside at its rest pressure P_W, as the triple tube's third-tube wall,
chambers.py), and what it gains the reserve's gas loses; the base valves'
discs displace reserve oil as in the triple tube.

Mono tube (Dixon 2007, sec. 1.4): the pressure tube is the outer tube (air
outside: its wall stretches with P - P_atm); piston valves only; the
floating piston (floating.py) at x_fp grows the compression chamber by
A_B x_fp and takes that volume from the gas.

Each part sweeps the area its pressures load (virtual work, as
damper.volumes of the triple tube).
"""

from __future__ import annotations

from numba import njit

from . import chambers as ch
from . import floating as fl
from . import intake as ik
from . import shims as sh
from .fluid import JIT
from .layout import PO, SO

CH, PR, BC, PI, BI = PO["chambers"], PO["piston_rebound"], PO["base_compression"], PO["piston_intake"], PO["base_intake"]
S_CH, S_PR, S_BC, S_PI, S_BI = SO["chambers"], SO["piston_rebound"], SO["base_compression"], SO["piston_intake"], SO["base_intake"]
TRIPLE, TWIN, MONO = 0, 1, 2  # chambers.ARCH
CODES = {"triple_tube_semi_active": TRIPLE, "twin_tube": TWIN, "mono_tube": MONO}


@njit(**JIT)
def volumes(y, p, s, sd, mono, fpo, P_out):
    """(V_r, dV_r, V_c, dV_c, V_sw, dV_sw, W_r, W_c) of a passive damper at
    stroke s [m] and rate sd [m/s] with the pressures held: chamber volumes
    [m^3] and rates [m^3/s], the volume V_sw [m^3] taken from the gas (twin:
    the base valves' discs and the pressure tube's stretch into the reserve;
    mono: the floating piston's stroke, state block at ``fpo``) and its rate
    without the walls' W dP terms, the walls' compliances W [m^3/Pa]
    against the pressure P_out [Pa] outside the pressure tube."""
    A_r, A_b = p[CH + ch.A_R], p[CH + ch.A_B]
    A0, A1 = p[PR + sh.A_EQ], p[PI + ik.A_P]
    x0, x1, v0, v1 = y[S_PR + sh.X], y[S_PI + ik.X], y[S_PR + sh.V], y[S_PI + ik.V]
    P_r, P_c = y[S_CH + ch.PR], y[S_CH + ch.PC]
    kw = p[CH + ch.KAPPA_PT] * A_b
    l_r, l_c = p[CH + ch.L_R0] - s, p[CH + ch.L_C0] + s
    W_r, W_c = kw * l_r, kw * l_c
    V_r = A_r * l_r + A0 * x0 - A1 * x1 + W_r * (P_r - P_out)
    dV_r = -A_r * sd + A0 * v0 - A1 * v1 - kw * sd * (P_r - P_out)
    V_c = A_b * l_c - A0 * x0 + A1 * x1 + W_c * (P_c - P_out)
    dV_c = A_b * sd - A0 * v0 + A1 * v1 + kw * sd * (P_c - P_out)
    if mono:
        V_sw = A_b * y[fpo + fl.X]
        dV_sw = A_b * y[fpo + fl.V]
        V_c += V_sw
        dV_c += dV_sw
        return V_r, dV_r, V_c, dV_c, V_sw, dV_sw, W_r, W_c
    V_base = p[BC + sh.A_EQ] * y[S_BC + sh.X] - p[BI + ik.A_P] * y[S_BI + ik.X]
    dV_base = p[BC + sh.A_EQ] * y[S_BC + sh.V] - p[BI + ik.A_P] * y[S_BI + ik.V]
    V_c += V_base
    dV_c += dV_base
    V_sw = V_base + W_r * (P_r - P_out) + W_c * (P_c - P_out)
    dV_sw = dV_base - kw * sd * (P_r - P_out) + kw * sd * (P_c - P_out)
    return V_r, dV_r, V_c, dV_c, V_sw, dV_sw, W_r, W_c


@njit(**JIT)
def rest(dy, start, stop):
    """The rates of an absent part's states [start, stop) are 0 (it is not built)."""
    for k in range(start, stop):
        dy[k] = 0.0
