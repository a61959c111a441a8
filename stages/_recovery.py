"""Recovery of the lab's truth by the calibrated model (issue 32, acceptance
5): the quantities where a truth quantity has a model counterpart, computed
on both sides. Pure functions (no file I/O; stages/recovery.py reads and
writes). SI units throughout.

- free gas at rest: volume of undissolved gas per volume of liquid at the
  rest state (precharge P0, oil temperature oil.T);
- oil modulus: tangent bulk modulus rho dP/drho [Pa] of the gas-free oil;
- valve lift-force curves: the force [N] holding a valve at lift x [m];
- top mount: dynamic stiffness |K*| [N/m] and loss angle [deg] of a sine.
"""

from __future__ import annotations

import math

import numpy as np

from dampertwin.calibration.identifiability import top_mount_dynamic_stiffness, valve_lift_force
from dampertwin.excitation import Excitation
from dampertwin.kpi import harmonic
from dampertwin.model.fluid import gas_fraction
from dampertwin.truth import gas as tgas
from dampertwin.truth import intake as tintake
from dampertwin.truth import shims as tshims
from dampertwin.truth.fluid import P_REF, modulus, ramp
from dampertwin.truth.layout import PO
from dampertwin.truth.params import INTAKES, SHIMS
from dampertwin.truth.run import simulate as truth_simulate

CURVE_POINTS = 41  # lifts from 0 to the flow bench's largest lift at which curves are compared
SINE_CYCLES = 6  # cycles of each dynamic-stiffness sine (the first is dropped), as identifiability
SINE_RATE = 5000.0  # [Hz] sample rate of the dynamic-stiffness sines, as identifiability


def rel_error(model: float, truth: float) -> float:
    """Signed relative error (model - truth) / |truth| [-]."""
    return (model - truth) / abs(truth)


# ------------------------------------------------------------- gas and oil
def model_free_gas(d) -> float:
    """Undissolved gas volume / liquid volume [-] of the model at rest
    (P = oil.P_0, T = oil.T): eq. 4.14-4.15, gas theta(P0) chi T/T_ref
    (P_ref/P0)^(1/Gamma), liquid (1 - chi) exp(-(P0 - P_ref)/K_oil), both per
    unit reference volume of emulsion; 0 with effects.gas_content off."""
    if float(d["effects.gas_content"]) < 0.5:
        return 0.0
    chi, P0, P_ref = float(d["oil.chi"]), float(d["oil.P_0"]), float(d["constants.P_ref"])
    theta, _ = gas_fraction(P0, float(d["oil.P_sat"]), float(d["oil.P_vap"]))
    gas = theta * chi * float(d["oil.T"]) / float(d["constants.T_ref"]) * (P_ref / P0) ** (1.0 / float(d["oil.Gamma"]))
    liquid = (1.0 - chi) * math.exp(-(P0 - P_ref) / float(d["oil.K_oil"]))
    return gas / liquid


def truth_free_gas(p: np.ndarray, P0: float) -> float:
    """Undissolved gas volume / liquid volume [-] of the truth at rest
    (precharge P0 [Pa]): the Henry equilibrium of the entrained gas,
    e = ALPHA_N + ramp(ALPHA_TOT - S_H P0/P_ref) [m^3 at P_ref per m^3 of
    liquid] (truth/gas.py free_gas_rate, the lab's rest state), at P0 as
    isothermal bubbles: e P_ref / P0 (truth/chambers.py)."""
    go, P_ref = PO["gas"], p[PO["oil"] + P_REF]
    e = p[go + tgas.ALPHA_N] + ramp(p[go + tgas.ALPHA_TOT] - p[go + tgas.S_H] * P0 / P_ref, tgas.ALPHA_EPS)
    return float(e * P_ref / P0)


def model_oil_modulus(d) -> float:
    """Tangent bulk modulus [Pa] of the model's gas-free oil at the design's
    oil.T: K_oil at every pressure (eq. 4.15 with chi = 0: rho ~ exp(P /
    K_oil); the oil_thermal candidate's factor is 1 at oil.T)."""
    return float(d["oil.K_oil"])


def truth_oil_modulus(p: np.ndarray, P: float) -> float:
    """Tangent bulk modulus [Pa] of the truth's gas-free oil at pressure P
    [Pa]: Murnaghan K0 + K1 (P - P_ref) (truth/fluid.py modulus; no
    temperature dependence there)."""
    return float(modulus(P, p, PO["oil"]))


# ------------------------------------------------------------------ valves
def model_lift_force(d, valve: str, lifts: np.ndarray) -> np.ndarray:
    """Spring force [N] of a model valve at ``lifts`` [m] (evenly spaced from
    0): F_pre + a(e^(bx) - 1) + c(e^(dx) - 1), eq. 4.19 (THESIS-ERRATA 17),
    through identifiability.valve_lift_force without a covariance."""
    g = d.group(valve)
    values = {"F_preload": g["F_preload"], "a": g["a"], "b": g["b"], "c": g["c"], "d": g["d"]}
    rows = valve_lift_force(values, [], np.zeros((0, 0)), 1.0, float(lifts[-1]), len(lifts))
    return np.array([r["force [N]"] for r in rows])


def truth_lift_force(p: np.ndarray, valve: str, lifts: np.ndarray) -> np.ndarray:
    """Elastic force [N] of a truth valve at ``lifts`` [m]: shim stacks
    truth.shims.elastic_force (plate bending with preload and backing set,
    without the shim-to-shim friction hysteresis), intake discs the coil
    spring F_S + K_S x (truth.intake)."""
    o = PO[valve]
    if valve in SHIMS:
        return np.array([tshims.elastic_force(float(x), p, o) for x in lifts])
    if valve in INTAKES:
        return p[o + tintake.F_S] + p[o + tintake.K_S] * np.asarray(lifts, float)
    raise ValueError(f"{valve}: not a shim stack or an intake valve")


def model_pressure_area(d, valve: str) -> float:
    """Area [m^2] the pressure drop acts on in the model: shim stacks
    pi/12 (D_d - D_i)(2 D_d + D_i) (eq. 4.21, THESIS-ERRATA 19), intake discs
    pi/4 (D_d^2 - D_h^2) (eq. 4.22)."""
    g = d.group(valve)
    if valve in SHIMS:
        return math.pi / 12.0 * (g["D_d"] - g["D_i"]) * (2.0 * g["D_d"] + g["D_i"])
    return math.pi / 4.0 * (g["D_d"] ** 2 - g["D_h"] ** 2)


def truth_pressure_area(p: np.ndarray, valve: str) -> float:
    """Area [m^2] the pressure drop acts on in the truth: the stack's
    equivalent area A_EQ (plate bending) or the closed disc's A_P (seat land
    with its leakage profile), as built."""
    o = PO[valve]
    return float(p[o + tshims.A_EQ] if valve in SHIMS else p[o + tintake.A_P])


def truth_bench_lift(p: np.ndarray, rest: dict, valve: str, run, bench: dict) -> float:
    """Largest lift [m] the truth's valve reaches on the flow-bench run
    ``run`` (ideal actuator and sensors; bench: volume and back pressure)."""
    r = truth_simulate(p, run.excitation, "valve", bench_valve=valve, bench=bench, rate=run.rate, rest=rest)
    if not r.ok:
        raise RuntimeError(f"truth flow bench of {valve} failed: {r.stats.message}")
    return float(np.max(r["lift [m]"]))


def curve_error(model: np.ndarray, truth: np.ndarray) -> float:
    """Largest relative error max |F_model - F_truth| / |F_truth| [-] over a curve."""
    return float(np.max(np.abs(np.asarray(model) - truth) / np.abs(truth)))


# --------------------------------------------------------------- top mount
def sine(frequency: float, amplitude: float) -> tuple[np.ndarray, np.ndarray]:
    """(time [s], displacement [m]) of the dynamic-stiffness sine, as
    identifiability.top_mount_dynamic_stiffness builds it."""
    t = np.arange(0.0, SINE_CYCLES / frequency, 1.0 / SINE_RATE)
    return t, amplitude * np.sin(2 * np.pi * frequency * t)


def truth_dynamic_stiffness(p: np.ndarray, rest: dict, frequencies, amplitude: float) -> list[dict]:
    """|K*| [N/m] and loss angle [deg] of the truth's top mount (its
    ``topmount`` configuration) for sines of ``amplitude`` [m]: first
    harmonic of force over displacement on all but the first cycle."""
    out = []
    for f in frequencies:
        t, x = sine(f, amplitude)
        r = truth_simulate(p, Excitation.from_samples(t, x), "topmount", rate=SINE_RATE, rest=rest)
        if not r.ok:
            raise RuntimeError(f"truth top mount at {f} Hz failed: {r.stats.message}")
        m = t >= 1.0 / f
        K = harmonic(t[m], np.asarray(r["top mount force [N]"])[m], f) / harmonic(t[m], x[m], f)
        out.append({"frequency [Hz]": float(f), "stiffness [N/m]": float(abs(K)),
                    "loss angle [deg]": float(np.degrees(np.angle(K)))})
    return out


def model_dynamic_stiffness(d, frequencies, amplitude: float) -> list[dict]:
    """|K*| [N/m] and loss angle [deg] of a model design's top mount on the
    same sines (identifiability.top_mount_dynamic_stiffness, no covariance)."""
    rows = top_mount_dynamic_stiffness(d, {}, [], np.zeros((0, 0)), 1.0, list(frequencies), amplitude,
                                       cycles=SINE_CYCLES, rate=SINE_RATE)
    return [{k: r[k] for k in ("frequency [Hz]", "stiffness [N/m]", "loss angle [deg]")} for r in rows]
