"""Leakage past the piston band (not in the thesis model; off in the
baseline design). Parameters: effect_parameters piston_leakage.gap (h, C)
and piston_leakage.length (L, F).

A worn or loose piston band leaves an annular gap h of length L around the
piston: laminar (Poiseuille) flow between the rebound and compression
chambers, Q = G (P_r - P_c) with G = pi D h^3 / (12 mu L) [m^3/(s Pa)]
(White, Viscous Fluid Flow, 3rd ed., eq. 3-44: narrow concentric annulus).
With the oil_thermal effect, mu follows the oil temperature: G nu0 / nu.

An approximation, deliberately: ``gap`` is the EQUIVALENT concentric
clearance. A band off-axis by a fraction e of its clearance h passes
(1 + 1.5 e^2) times the concentric flow (narrow eccentric annulus; Merritt,
Hydraulic Control Systems, 1967), so the fitted
gap is h (1 + 1.5 e^2)^(1/3) (52 um for an eccentric 47 um at e = 0.5); the
Couette flow the moving piston drags through the gap (pi D h ds/dt / 2,
13 % of the pressure flow at 30 um, 13 Hz +-5 mm) and the band's shear
force are left out, so the fitted gap absorbs them too.
"""

from __future__ import annotations

import math

from numba import njit

from .declarations import Parameter


def _conductance(d):
    if "piston_leakage.gap" not in d.effect_params:  # the design does not declare the effect
        return 0.0
    mu = d["oil.rho_oil"] * d["oil.nu"]
    return math.pi * d["geometry.D_PT"] * d["piston_leakage.gap"] ** 3 / (12.0 * mu * d["piston_leakage.length"])


PARAMETERS = (
    Parameter("G_LEAK", "m^3/(s Pa)", _conductance, "laminar conductance of the piston-band gap"),
    Parameter("E_LEAK", "-", "effects.piston_leakage", "switch: piston-band leakage"),
)


@njit(cache=True, error_model="numpy")
def leakage_flow(G, P_r, P_c):
    """Laminar leakage rebound -> compression [m^3/s]."""
    return G * (P_r - P_c)


@njit(cache=True, error_model="numpy", inline="always")
def leakage(p, P_r, P_c, fluidity):
    """The leakage submodel in the assembled model [m^3/s] (0 when off);
    ``fluidity`` = nu0 / nu (1.0 at the design's oil temperature)."""
    if p[_L.P.E_LEAK] > 0.5:
        return leakage_flow(p[_L.P.G_LEAK] * fluidity, P_r, P_c)
    return 0.0


from . import layout as _L  # noqa: E402  (bottom: layout reads this file's declarations first)
