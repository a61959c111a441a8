"""Friction-only configuration: the rod-friction law (LuGre with Stribeck
curve, thesis eq. 4.38-4.41, errata 34) driven by a prescribed sliding
velocity, as on a friction test device (no damper, no hydraulics).

Two effects of the library apply on request (both off by default; off is
bit-identical to the plain law):

- asymmetric friction: the Coulomb and static levels scaled by
  f(v) = 1 + a tanh(v / v_reg) (Olsson et al., Eur. J. Control 4 (1998)
  176-195, sec. 3.6), :func:`~.rod_friction_asymmetric.direction_factor`.
  On the friction device (no gas force, no precharge) a direction-dependent
  Coulomb level is measurable; in the damper it is an offset, so the
  library's ``rod_friction_asymmetric`` scales the film (velocity-dependent)
  parts instead;
- free play (the dead-zone backlash of ``top_mount_backlash``, Nordin &
  Gutman, Automatica 38 (2002) 1633-1649, eq. 2) in series with the bristles:
  the elastic force is k_b D(z), D(z) = z - delta sign(z) for |z| > delta,
  else 0, and the bristle rate of eq. 4.40 uses that force,
  dz/dt = v - |v| k_b D(z) / g(v). Across the play (|z| <= delta) nothing
  is in contact: the elastic force is zero and z follows the motion.

Integration: per substep the velocity is frozen and the bristle state takes
the exact solution of its linear ODE in each region (contact side or play),
with the exact crossing time between them, so any stiffness k_b is stable
and the dead zone needs no rounding constant.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .rod_friction import lugre, stribeck
from .rod_friction_asymmetric import direction_factor

EXP_TINY = 1e-12  # [-] a*h below this: the exponential update is replaced by its linear limit


@njit(cache=True)
def _plain_series(t, v, z0, F_c, F_s, k_b, s2, c_comp, vd, a_s, alpha_s, substeps):
    """Plain LuGre law (no effects)."""
    n = len(t)
    F = np.empty(n)
    z = z0
    for i in range(n):
        dz, F[i] = lugre(z, v[i], k_b, F_c, F_s, s2, c_comp, vd, a_s, alpha_s)
        if i == n - 1:
            break
        h = (t[i + 1] - t[i]) / substeps
        for k in range(substeps):
            vm = v[i] + (v[i + 1] - v[i]) * (k + 0.5) / substeps
            a = k_b * abs(vm) / stribeck(vm, F_c, F_s, a_s, alpha_s)
            if a * h < EXP_TINY:
                z += vm * h
            else:
                zs = vm / a
                z = zs + (z - zs) * math.exp(-a * h)
    return F


@njit(cache=True)
def _elastic(z, delta):
    """Deflection beyond the free play D(z) [m]."""
    if z > delta:
        return z - delta
    if z < -delta:
        return z + delta
    return 0.0


@njit(cache=True)
def _advance(z, vm, a, delta, h):
    """Bristle state after h [s] at frozen velocity vm with rate coefficient
    a = k_b |vm| / g [1/s]: exact in contact and in the play, with the exact
    time at which contact is left or made."""
    for _ in range(4):  # contact -> play -> contact at most
        if h <= 0.0:
            break
        if -delta <= z <= delta:  # in the play: z follows the motion
            if vm == 0.0:
                break
            edge = delta if vm > 0.0 else -delta
            tau = (edge - z) / vm
            if tau >= h:
                z += vm * h
                break
            z = edge
            h -= tau
            # at the edge moving outwards: in contact from here on
            w = 0.0
            s = 1.0 if vm > 0.0 else -1.0
        else:
            s = 1.0 if z > 0.0 else -1.0
            w = z - s * delta
        if a * h < EXP_TINY:
            w_new = w + vm * h
        else:
            ws = vm / a
            w_new = ws + (w - ws) * math.exp(-a * h)
        if w_new * s >= 0.0:  # still on side s
            return w_new + s * delta
        # contact left at w = 0: tau from w(tau) = 0
        if a * h < EXP_TINY:
            tau = -w / vm
        else:
            ws = vm / a
            tau = math.log((w - ws) / (-ws)) / a
        z = s * delta  # at the edge of the play, moving inwards: the loop continues there
        h -= tau
    return z


@njit(cache=True)
def _effect_series(t, v, z0, F_c, F_s, k_b, s2, c_comp, vd, a_s, alpha_s, a_asym, v_reg, delta, substeps):
    """LuGre law with direction factor (a_asym) and free play (delta)."""
    n = len(t)
    F = np.empty(n)
    z = z0
    for i in range(n):
        f = direction_factor(a_asym, v[i], v_reg)
        g = stribeck(v[i], F_c * f, F_s * f, a_s, alpha_s)
        e = _elastic(z, delta)
        dz = v[i] - k_b * abs(v[i]) / g * e
        s1 = c_comp * math.exp(-((v[i] / vd) ** 2))
        F[i] = k_b * e + s1 * dz + s2 * v[i]
        if i == n - 1:
            break
        h = (t[i + 1] - t[i]) / substeps
        for k in range(substeps):
            vm = v[i] + (v[i + 1] - v[i]) * (k + 0.5) / substeps
            fm = direction_factor(a_asym, vm, v_reg)
            a = k_b * abs(vm) / stribeck(vm, F_c * fm, F_s * fm, a_s, alpha_s)
            z = _advance(z, vm, a, delta, h)
    return F


def simulate_friction(t, velocity, *, F_c, F_s, k_b, s2, c_comp, vd, a_s, alpha_s, a: float = 0.0,
                      v_reg: float = 1e-3, delta: float = 0.0, z0: float = 0.0, substeps: int = 4) -> np.ndarray:
    """Friction force [N] (positive opposing positive velocity) on the
    samples of t [s] for the sliding velocity [m/s] (linear between
    samples). ``a`` [-], ``v_reg`` [m/s]: asymmetric friction; ``delta``
    [m]: half width of the free play; a = 0 and delta = 0 are the plain law,
    bit-identical."""
    t = np.ascontiguousarray(t, float)
    v = np.ascontiguousarray(velocity, float)
    if a == 0.0 and delta == 0.0:
        return _plain_series(t, v, float(z0), float(F_c), float(F_s), float(k_b), float(s2), float(c_comp),
                             float(vd), float(a_s), float(alpha_s), int(substeps))
    if not -1.0 < a < 1.0 or delta < 0.0 or v_reg <= 0.0:
        raise ValueError(f"friction effects: need -1 < a < 1 (got {a}), delta >= 0 (got {delta}), v_reg > 0")
    return _effect_series(t, v, float(z0), float(F_c), float(F_s), float(k_b), float(s2), float(c_comp), float(vd),
                          float(a_s), float(alpha_s), float(a), float(v_reg), float(delta), int(substeps))


def lugre_force(dv, z, *, F_c, F_s, k_b, s2, c_comp, vd, a_s, alpha_s):
    """LuGre rod friction (eq. 4.38-4.41) with keyword arguments named as in
    the design YAML. dv: sliding velocity [m/s], z: bristle deflection [m].
    Returns (dz/dt [m/s], force [N], positive opposing positive dv)."""
    return lugre(float(z), float(dv), k_b, F_c, F_s, s2, c_comp, vd, a_s, alpha_s)


__all__ = ["simulate_friction", "lugre_force"]
