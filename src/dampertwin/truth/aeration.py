"""Air entrained from the reserve at low reserve pressure (truth effect
``air_entrainment``, off unless a sample names it).

The reserve's gas sits on the free oil surface above the base valve. When
its pressure P_res is low (a lost precharge, a deep rebound stroke) the
intake flow through the base valve draws gas from that surface into the
compression chamber. Entrainment grows as the pressure falls: the intake
flow Q_in [m^3/s] carries the volume fraction

    phi = PHI_E (1 - P_res / P_E)+        (gas at P_res per volume of oil)

below the onset pressure P_E (zero above it); Gholizadeh, Burton &
Schoenau, Int. J. Fluid Power 13 (2012) 7, review the entrainment of free
air by low-pressure suction flows, and Lang (PhD thesis, Univ. Michigan
1977, ch. 5) observed the gas-spring-like lag of twin-tube dampers it
causes; the linear onset is this truth's assumption. The entrained bubbles
(g_e [m^3 at P_ref], isothermal at the oil temperature, compressed with the
compression chamber's pressure) are released back to the reserve at a
finite rate g_e / TAU_E (de-aeration, TAU_E ~ 1 s: Gholizadeh et al. 2012,
4). The gas mass moves, it is not created: what the oil takes the reserve
gas loses, what is released it regains (tests/test_truth_effects.py).
"""

from __future__ import annotations

from numba import njit

from .fluid import JIT

PARAMS = ("P_E", "PHI_E", "TAU_E", "ON")
P_E, PHI_E, TAU_E, ON = range(len(PARAMS))
STATES = (("g_e", "m^3", 1e-7, "air entrained in the compression chamber"),)
GE = 0


@njit(**JIT)
def entrainment(g_e, Q_in, P_res, P_ref, p, o):
    """(entrainment, release) rates [m^3/s at P_ref] of the compression
    chamber's entrained gas g_e for the intake flow Q_in [m^3/s] out of the
    reserve at pressure P_res [Pa] (no entrainment for a flow into the reserve)."""
    phi = p[o + PHI_E] * max(1.0 - P_res / p[o + P_E], 0.0)
    return phi * max(Q_in, 0.0) * P_res / P_ref, g_e / p[o + TAU_E]
