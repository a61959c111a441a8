"""Two-node thermal network of the truth (effect ``two_node_thermal``, off
unless a sample names it; on, it replaces the one-node oil heating of
chambers.oil_heating).

Lumped capacitances (Incropera & DeWitt, Fundamentals of Heat and Mass
Transfer, 6th ed. 2007, 5.2 lumped capacitance, 3.1.3 thermal circuits):
the oil node (capacity C_OIL [J/K]) takes the dissipated power and the heat
from the reserve gas and passes G_OW (T_oil - T_w) [W] to the tubes' steel
node (C_W); the steel loses HA (T_w - T_amb) to the air (the one-node
model's conductance, chambers.HA):

    C_OIL dT_oil/dt = P_loss - G_OW (T_oil - T_w)
    C_W   dT_w/dt   = G_OW (T_oil - T_w) - HA (T_w - T_amb)

The reserve gas exchanges heat with the oil as before (gas.py), so it
follows the oil node. With G_OW -> infinity the nodes move together and
the network is the one-node law with C_TH = C_OIL + C_W
(tests/test_truth_effects.py). Capacities: 0.3 kg oil x 1.9 kJ/(kg K) and
1.4 kg steel x 0.45 kJ/(kg K) (Calvo et al., Int. J. Vehicle Design 2009,
the masses of chambers.C_TH, whose 1200 J/K they sum to); G_OW from forced convection in the tubes,
h ~ 250 W/(m^2 K) over ~0.04 m^2 of wetted steel.
"""

from __future__ import annotations

from numba import njit

from .fluid import JIT

PARAMS = ("C_OIL", "C_W", "G_OW", "ON")
C_OIL, C_W, G_OW, ON = range(len(PARAMS))
STATES = (("T_w", "K", 1.0, "tube steel temperature"),)
TW = 0


@njit(**JIT)
def two_node(T_oil, T_w, P_loss, HA, T_amb, p, o):
    """(dT_oil/dt, dT_w/dt) [K/s] of the oil and steel nodes under the
    power P_loss [W] into the oil."""
    q_ow = p[o + G_OW] * (T_oil - T_w)
    return (P_loss - q_ow) / p[o + C_OIL], (q_ow - HA * (T_w - T_amb)) / p[o + C_W]
