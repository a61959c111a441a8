"""The virtual laboratory's measurement of one run (dampertwin.lab): the
servo-hydraulic actuator, the hidden sample's truth (lab 3) or the model on
the sample's part (lab 2), and the benches' transducers on the recorded
channels."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pandas as pd
from scipy import signal

from .design import Design
from .excitation import Excitation
from .lab_sample import (TEMPERATURE, TEMPERATURE_DEFAULTS, LabError, _sensor_specs, is_truth_sample, sample_design,
                         truth_part)
from .protocols import Run
from .sensors import quantise, transducer
from .simulation import simulate

TRUTH_RTOL = 1e-8        # the truth's integration tolerance (the fits: 1e-4)
# The truth's absolute error floor, in units of each state's declared scale
# (solver.integrate scales the states: 3e-7 of 10 N for a Dahl friction force,
# of 1 m/s for a valve velocity, of 0.1 m/s for the rod). With atol = rtol =
# 1e-8 the states that cross zero (Dahl forces, valve and rod velocities)
# set ~80 % of the step sizes at a floor far below anything recorded. With the
# round-1 scales (1 N, 0.01 m/s) 1e-6 took 2.5x fewer steps than 1e-8 on the
# module random test and moved the recorded channels by < 1e-3 N / 1e-3 m/s^2,
# far below the sensors' noise and resolution (bench/README.md "Lab time").
# Issue 9 raised the Dahl and rod scales 10x (bench/README.md "State scales"):
# 1e-6 then moved the rod acceleration by 8e-4 m/s^2, more than 1/20 of the
# 0.01 m/s^2 converter step that tests/test_lab.py allows; 3e-7 passes it and
# costs 20 % more lab time (35 files: 33.7 s against 28.2 s wall, 2 cores).
TRUTH_ATOL = 3e-7
# the thermocouple on the outer tube when the sample's benches do not describe one: first order with a
# 1.3 s time constant (the protocols document 1 s), 0.1 K converter step, 0.03 K noise (type-K thermocouple
# with a cold-junction amplifier: IEC 60584-1 class 1 tolerances are a fixed offset, which the rise ignores)
THERMOCOUPLE = {"filter": "butter", "order": 1, "corner": 0.12, "gain": 1.0, "offset": 0.0, "resolution": 0.1}
THERMOCOUPLE_NOISE = 0.03  # [K] one sigma
# the friction test's gas fill when the sample's benches do not describe it: the rig fills the reserve gas to
# the set precharge (the recorded value) through a 0-25 bar gauge of 0.25 % FS class: the real precharge is
# +5 kPa off (zero error) and scatters by 0.3 % from fill to fill
PRECHARGE_FILL = {"offset": 5000.0, "scatter": 0.003}
DEFLECTION = "top mount deflection [m]"
# the module test's LVDT (thesis 7.2, fig. 7.2: on the rod through an adapter, its body on the top-mount
# housing; zeroed on the unloaded mount) when the sample's benches do not describe one: the carrier
# demodulator's 2nd-order Bessel filter at 600 Hz (conf/test documents a 2nd-order Butterworth at 500 Hz),
# 0.4 % gain and 20 um zero error, 0.1 um converter step, 1 um noise (a +-5 mm AC LVDT with its conditioner)
LVDT = {"filter": "bessel", "order": 2, "corner": 600.0, "gain": 0.996, "offset": 2.0e-5, "resolution": 1.0e-7}
LVDT_NOISE = 1.0e-6  # [m] one sigma


def actuate(ex: Excitation, gain: float, delay: float, natural_frequency: float | None = None,
            damping: float | None = None) -> Excitation:
    """The motion (or flow) a servo-hydraulic actuator really produces for
    the target ``ex``: delayed by ``delay`` [s], scaled by ``gain`` and, when
    given, filtered by its closed position loop, a 2nd-order system
    x'' + 2 zeta w x' + w^2 x = w^2 u (w = 2 pi natural_frequency), started
    at rest. The recorded displacement is this real motion (thesis 6.5)."""
    t = ex.t0 + ex.dt * np.arange(len(ex.value))
    u = gain * np.interp(t - delay, t, ex.value, left=ex.value[0])
    if natural_frequency is None:
        r = gain * np.interp(t - delay, t, ex.rate, left=0.0)
        return replace(ex, value=u, rate=r)
    w = 2.0 * math.pi * natural_frequency
    sys = signal.StateSpace([[0.0, 1.0], [-w * w, -2.0 * damping * w]], [[0.0], [w * w]], np.eye(2), np.zeros((2, 1)))
    _, y, _ = signal.lsim(sys, u, t - t[0], X0=[u[0], 0.0], interp=True)
    return replace(ex, value=np.ascontiguousarray(y[:, 0]), rate=np.ascontiguousarray(y[:, 1]))


def record(run: Run, design: Design, sample: dict, rng: np.random.Generator, bench: dict | None = None,
           oil_dT: float = 0.0, gain_scatter: float = 1.0, temperature: bool = False,
           nominal: Design | None = None, deflection: bool = False) -> pd.DataFrame:
    """Measure one run on the hidden sample behind ``design`` with the oil
    ``oil_dT`` [K] warmer than the design's and the actuator gain scattered;
    ``temperature``: the oil temperature recorded too (a thermocouple);
    ``deflection``: a module run's rod against the top-mount housing too (LVDT). A run
    with ``meta["precharge [Pa]"]`` (friction test) is measured with the reserve
    gas filled to it (with the fill's error, PRECHARGE_FILL) and records it."""
    b = sample["benches"]
    a = b["actuator"]
    real = actuate(run.excitation, a["gain"] * gain_scatter, a["delay"], a.get("natural_frequency"), a.get("damping"))
    precharge = run.meta.get("precharge [Pa]")
    if is_truth_sample(sample):
        r = _truth_run(run, design, sample, rng, bench, oil_dT, real, precharge, nominal)
    else:
        r = _model_run(run, design, sample, rng, bench, oil_dT, real, precharge)
    if deflection and run.configuration != "module":
        raise LabError(f"{run.test}/{run.name}: the top-mount deflection (LVDT) is a module test's channel, "
                       f"not of configuration {run.configuration!r}")
    return _recorded(run, r, b, rng, precharge, oil_dT, temperature, deflection)


def _truth_run(run, design, sample, rng, bench, oil_dT, real, precharge, nominal):
    """One run on the truth of a lab-3 sample: its own oil physics at the
    oil temperature (no viscosity / modulus factors)."""
    from .truth.run import simulate as truth_simulate

    P0 = None
    if precharge is not None:
        pf = {**PRECHARGE_FILL, **sample["benches"].get("precharge", {})}
        P0 = (float(precharge) + pf["offset"]) * (1.0 + pf["scatter"] * rng.standard_normal())
    p, rest = truth_part(design, nominal if nominal is not None else design, sample, P0)
    r = truth_simulate(p, real, run.configuration, current=run.current, bench_valve=run.bench_valve, bench=bench,
                       rate=run.rate, rest=rest, oil_T=rest["T"] + oil_dT)
    if not r.ok:
        raise LabError(f"lab (truth) simulation of {run.test}/{run.name} failed: {r.stats.message}")
    return r


def _model_run(run, design, sample, rng, bench, oil_dT, real, precharge):
    """One run of a lab-2 sample: the model's equations on the sample's part."""
    b = sample["benches"]
    part = sample_design(design, sample)
    if precharge is not None:  # the friction test refills the reserve gas to the run's precharge (recorded)
        pf = {**PRECHARGE_FILL, **b.get("precharge", {})}
        p_real = (float(precharge) + pf["offset"]) * (1.0 + pf["scatter"] * rng.standard_normal())
        part = part.with_overrides({"oil.P_0": p_real})
    if oil_dT:
        tc = {**TEMPERATURE_DEFAULTS, **b.get("temperature", {})}
        part = part.with_overrides({"oil.nu": part["oil.nu"] * math.exp(tc["viscosity_per_K"] * oil_dT),
                                    "oil.K_oil": part["oil.K_oil"] * math.exp(tc["modulus_per_K"] * oil_dT)})
    r = simulate(part, real, run.configuration, current=run.current, bench_valve=run.bench_valve,
                 rate=run.rate, bench=bench, rtol=TRUTH_RTOL, atol=TRUTH_ATOL, method="rodas4")
    if not r.ok:
        raise LabError(f"lab simulation of {run.test}/{run.name} failed: {r.stats.message}")
    return r


def _recorded(run, r, b, rng, precharge, oil_dT, temperature, deflection=False) -> pd.DataFrame:
    """The benches' transducers on a run's channels."""
    fs = run.rate
    noise = {TEMPERATURE: THERMOCOUPLE_NOISE, DEFLECTION: LVDT_NOISE, **b["noise"]}
    specs = {TEMPERATURE: THERMOCOUPLE, DEFLECTION: LVDT, **_sensor_specs(b)}

    def meas(name: str, x: np.ndarray) -> np.ndarray:
        s = specs.get(name, {})
        y = transducer(x, fs, **{k: v for k, v in s.items() if k != "resolution"})
        y = y + noise.get(name, 0.0) * rng.standard_normal(len(y))
        return quantise(y, s.get("resolution", 0.0))

    cols = {"time [s]": r.time}
    if run.configuration in ("valve", "active_valve"):
        cols["flow [m^3/s]"] = meas("flow [m^3/s]", r["flow [m^3/s]"])
        cols["dp [Pa]"] = meas("dp [Pa]", r["dp [Pa]"])
        if run.configuration == "active_valve":
            cols["current [A]"] = np.full(len(r.time), run.current)
    else:
        cols["displacement [m]"] = meas("displacement [m]", r["displacement [m]"])
        if run.configuration == "damper":
            cols["force [N]"] = meas("force [N]", r["rod force [N]"])
        else:  # load cell above the top mount
            cols["force [N]"] = meas("force [N]", r["top mount force [N]"])
        if run.configuration == "module":
            cols["rod acceleration [m/s^2]"] = meas("rod acceleration [m/s^2]", r["rod acceleration [m/s^2]"])
        if run.configuration in ("damper", "module"):
            cols["current [A]"] = np.full(len(r.time), run.current)
        if precharge is not None:
            cols["precharge [Pa]"] = np.full(len(r.time), float(precharge))
        if temperature:  # drawn last: the other channels' noise is that of a record without it
            T_oil = r[TEMPERATURE] if isinstance(r, _truth_result()) else r[TEMPERATURE] + oil_dT
            cols[TEMPERATURE] = meas(TEMPERATURE, T_oil)
        if deflection:  # drawn after the others: their noise is that of a record without it
            if isinstance(r, _truth_result()):
                X = r[DEFLECTION]
            else:  # the model's rod is on a rigid crosshead: its position u - s is the mount's deflection
                X = np.asarray(r["displacement [m]"]) - np.asarray(r["stroke [m]"])
            cols[DEFLECTION] = meas(DEFLECTION, X)
    df = pd.DataFrame(cols)
    df.insert(0, "run", run.name)
    return df


def _truth_result():
    from .truth.run import TruthResult

    return TruthResult
