"""Resonance of the test rig's fixture under the load cell, a measurement-chain
effect (thesis 7.3: the rig's spectrum above 500 Hz "most likely originated
from the imperfect mounting structure"; thesis 2.7.3: strain-gauge load cells
have limited high-frequency capability; not in the thesis model; off in the
baseline design).

The specimen pushes on the rig's crosshead, a mass on the load cell's
stiffness with some damping; the load cell reads its own spring and damper
force, not the specimen's force. A base-excited single-degree-of-freedom
system (Thomson & Dahmouni, Theory of Vibration with Applications, 5th ed.,
1998, 3.5, force transmissibility; Harris' Shock and Vibration Handbook,
6th ed., 2010, ch. 2): with the spring force F_s = K x [N] and G = K x'
[N/s] as states, natural frequency w = 2 pi f_n [rad/s] and damping ratio
zeta [-] (C/K = 2 zeta / w),

    dF_s/dt = G,    dG/dt = w^2 (F_in - F_s) - 2 zeta w G,
    F_lc = F_s + (2 zeta / w) G,

i.e. F_lc(s) / F_in(s) = (1 + 2 zeta s/w) / (1 + 2 zeta s/w + s^2/w^2): 1 at
low frequency, sqrt(1 + 4 zeta^2) / (2 zeta) at f_n. Only two parameters: the
crosshead's mass and the cell's stiffness enter as their ratio; its motion
(F/K, ~10 um) is left out of the stroke, so the damper itself is unchanged:
the effect changes what the force channel records (``rod force [N]`` in the
damper, ``top mount force [N]`` in the module configuration), nothing else.
The rod accelerometer's own mount (another resonance, on the other channel)
is not this effect. F_in is the rod force (damper) or the top-mount force
(module); both are (P0 - P_atm)(A_r - A_b) at rest. Two states, in the
extended configurations only (layout.variant).
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter, State

PARAMETERS = (
    Parameter("FX_FN", "Hz", "fixture_resonance.f_n", "natural frequency of the fixture on the load cell"),
    Parameter("FX_ZETA", "-", "fixture_resonance.zeta", "damping ratio of the fixture resonance"),
    Parameter("E_FIXTURE", "-", "effects.fixture_resonance", "switch: fixture resonance in the force channel"),
)


def _rest_force(q):
    """Static force on the load cell [N]: the gas force on the rod (THESIS-ERRATA 5)."""
    return (q["P0"] - q["P_ATM"]) * (q["A_R"] - q["A_B"])


STATES = (
    State("F_cell", "N", 1e2, _rest_force, "spring force of the load cell under the fixture"),
    State("dF_cell", "N/s", 1e5, 0.0, "its rate (the cell's stiffness times the fixture's velocity)"),
)


@njit(cache=True, error_model="numpy")
def cell_rates(F_s, G, F_in, f_n, zeta):
    """(dF_s/dt [N/s], dG/dt [N/s^2]) of the fixture driven by the force F_in [N]."""
    w = 2.0 * math.pi * f_n
    return G, w * w * (F_in - F_s) - 2.0 * zeta * w * G


@njit(cache=True, error_model="numpy")
def cell_reading(F_s, G, f_n, zeta):
    """Force the load cell reads [N]: its spring plus its damper, F_s + (2 zeta / w) G."""
    return F_s + 2.0 * zeta / (2.0 * math.pi * f_n) * G


@njit(cache=True, error_model="numpy", inline="always")
def load_cell(y, o, p, F_in, dy):
    """The fixture in the assembled (extended) model: returns the force the
    load cell reads [N] for the force F_in [N] on the fixture (states at
    y[o], y[o + 1]; their rates written); ``F_in`` itself when off."""
    if p[_L.P.E_FIXTURE] > 0.5:
        f_n, zeta = p[_L.P.FX_FN], p[_L.P.FX_ZETA]
        dy[o], dy[o + 1] = cell_rates(y[o], y[o + 1], F_in, f_n, zeta)
        return cell_reading(y[o], y[o + 1], f_n, zeta)
    dy[o] = 0.0
    dy[o + 1] = 0.0
    return F_in


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
