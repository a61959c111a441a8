"""Free play of the top mount (truth effect ``top_mount_free_play``, off
unless a sample names it): an axial clearance between the rod's nut /
washers and the mount's inner sleeve, closed by an impact contact on either
side, in series with the rubber mount (mount.py).

The sleeve (mass M_S) sits on the rubber; the rod moves freely inside
+-GAP [m] (half-width of the play) of it. Each side closes with a
Hunt-Crossley contact, F = K delta^1.5 (1 + LAM d delta/dt) for the
penetration delta > 0 (Hunt & Crossley, J. Appl. Mech. 42 (1975) 440; the
exponent 1.5 of a Hertzian contact and LAM = 3 (1 - e) / (2 v_in) from the
coefficient of restitution e: Gilardi & Sharf, Mech. Mach. Theory 37
(2002) 1213, eq. 17-19). The contact never pulls (the damping factor is
clipped at zero, fluid.hunt_crossley) and is exactly zero inside the
clearance (the penetration's rounding EPS = 10 nm underflows to 0 from
~8 um inside the edge; at the edge it leaves K EPS^1.5 ~ 1e-2 N). A worn mount
knocks: the force reaches the load cell through the sleeve and the rubber
only after the play is taken up.
"""

from __future__ import annotations

from numba import njit

from .fluid import JIT, hunt_crossley

PARAMS = ("GAP", "K", "LAM", "EPS", "M_S", "ON")
GAP, K, LAM, EPS, M_S, ON = range(len(PARAMS))
STATES = (("x_s", "m", 1e-4, "top-mount inner sleeve displacement"),
          ("v_s", "m/s", 0.1, "top-mount inner sleeve velocity"))
XS, VS = range(len(STATES))


@njit(**JIT)
def contact(x_rel, v_rel, p, o):
    """Force the sleeve puts on the rod through the play [N], positive
    pulling the rod down (tension, as the mount's force): the rod x_rel [m]
    above the sleeve at v_rel [m/s]; and the contact's dissipated power [W]
    (>= 0)."""
    gap = p[o + GAP]
    up, d_up = hunt_crossley(x_rel - gap, v_rel, p[o + K], p[o + LAM], p[o + EPS])
    down, d_down = hunt_crossley(-x_rel - gap, -v_rel, p[o + K], p[o + LAM], p[o + EPS])
    return up - down, d_up + d_down


def rest_offset(F: float, gap: float, k: float) -> float:
    """Rod position above the sleeve [m] at rest under the static force F
    [N] (tension positive): against one side of the play, pressed in by
    (|F| / K)^(2/3)."""
    d = (abs(F) / k) ** (2.0 / 3.0)
    return (gap + d) if F >= 0 else -(gap + d)
