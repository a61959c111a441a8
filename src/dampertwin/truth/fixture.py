"""Test fixture of the truth: the crosshead and load cell above the
specimen, a mass M_F on the load cell's stiffness K_F with damping C_F.

The thesis attributes its rig's spectrum above 500 Hz to the mounting
(ch. 7): the fixture resonates at sqrt(K_F / M_F) / (2 pi). The load cell
reads K_F x_f + C_F v_f, not the specimen's force.
"""

from __future__ import annotations

from numba import njit

from .fluid import JIT

PARAMS = ("M_F", "K_F", "C_F", "ON")
M_F, K_F, C_F, ON = range(len(PARAMS))
STATES = (("x_f", "m", 1e-6, "crosshead displacement"), ("v_f", "m/s", 1e-3, "crosshead velocity"))
XF, VF = range(len(STATES))


@njit(**JIT)
def fixture(y, s, p, o, F_in, dy):
    """Crosshead under the specimen's force F_in [N]: writes its rates;
    returns (load-cell force [N], dissipated power [W]). Off: rigid (the
    load cell reads F_in)."""
    if p[o + ON] < 0.5:
        dy[s + XF] = 0.0
        dy[s + VF] = 0.0
        return F_in, 0.0
    x = y[s + XF]
    v = y[s + VF]
    F_lc = p[o + K_F] * x + p[o + C_F] * v
    dy[s + XF] = v
    dy[s + VF] = (F_in - F_lc) / p[o + M_F]
    return F_lc, p[o + C_F] * v * v
