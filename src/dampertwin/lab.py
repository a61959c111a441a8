"""The virtual laboratory: SYNTHETIC reference "measurements".

No public measurements of this damper type exist, so a hidden physical
sample (a YAML like ``conf/lab/sample.yaml``: each design case's nominal
values with the deviations of a real part, hidden effects switched on, and
the imperfections of the benches) is run through the standard tests. Every
file says ``synthetic: true`` in its metadata, with the sample file's hash.

The lab is not the fitted model's path (no inverse crime):

- the truth is integrated at ``TRUTH_RTOL`` = 1e-8 (the fits run at
  simulation.DEFAULT_RTOL = 1e-4), with an absolute floor ``TRUTH_ATOL``
  of 1e-6 state scales (see there);
- the real part may carry effects the model under test lacks (``effects:``);
- the benches are not what the fits assume: the transducers have their own
  filters (e.g. 4th-order Bessel at 1.3 kHz where ``conf/test`` documents a
  2nd-order Butterworth at 1 kHz), gain and offset errors, noise and the
  converter's quantisation; the servo-hydraulic actuator has its own
  closed-loop dynamics (2nd order + delay), and the recorded displacement is
  the real motion; the oil temperature drifts slowly along a test sequence
  and scatters between runs (viscosity and bulk modulus follow it), as does
  the actuator gain.

A ``dampertwin-lab 3`` sample (``generator: dampertwin-lab 3``, a ``truth:``
section instead of ``factors`` / ``values`` / ``effects``) is measured on the
reference damper of :mod:`dampertwin.truth`, written from other physics than
the model (issue 32); its records name the truth's version. Lab-2 samples
(``conf/lab/lab2/``) keep the path above: the committed data/measured.

Only this module, the ``dampertwin lab`` command and the tests read
``conf/lab/``; calibration never does. The shipped samples were built from
``conf/lab/nominal.yaml``, a frozen copy of the baseline drawings: editing
``conf/design/baseline.yaml`` changes the model, not the parts on the shelf.

A lab-3 sample of a passive damper (its nominal design's ``architecture:``
twin_tube or mono_tube, e.g. ``conf/lab/twin_tube_sample.yaml``) runs the
tests a passive damper can run (lab_passive.PASSIVE_TESTS: the damper-level
sine tests at current 0, the flow bench of the valves it has);
lab_passive.measure_excitation records the truth for any displacement
excitation (a dyno run).
"""

from __future__ import annotations

import hashlib
import math
import os
import zlib
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import replace
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import signal

from . import __version__
from .design import ConfigTextError, Design, DesignError, yaml_load_file
from .design import load as load_design
from .errors import UserError
from .excitation import Excitation
from .io import write_frame
from .lab_passive import DEFAULT_ARCHITECTURE, PASSIVE_VALVES, passive_runs
from .protocols import Run, build_runs, flow_bench, load_all
from .sensors import FILTERS, quantise, transducer
from .simulation import simulate
from .variants import TOP_MOUNTS, VALVE_DESIGNS, Variant, load_variants

LAB_VERSION = "dampertwin-lab 2"
LAB3_VERSION = "dampertwin-lab 3"  # the truth of other physics (dampertwin.truth)
# The sample the DVC lab stage measures: the lab-3 sample, measured on the truth of other physics
# (dampertwin.truth). "lab2/sample.yaml" (the model's own equations, the lab of rounds 1-2) stays for the tests
# that need a truth with a model counterpart for every parameter.
STAGE_SAMPLE = "sample.yaml"
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
REST_S = 20.0            # [s] pause between two runs of a test sequence (temperature drift clock)
# recorded on the baseline when declared; module_topmount: the module-level top-mount test (thesis 7.2, fig. 7.2)
APPROACH2_TESTS = ("training", "verification", "monosine16", "module_topmount")
EXTRA_TESTS = ("thermal", "friction")
  # recorded on the baseline when conf/test declares them (issue 11)
TEMPERATURE = "oil temperature [K]"
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

REQUIRED_KEYS = ("factors", "values", "effects", "benches")
REQUIRED_KEYS_3 = ("truth", "benches")
TRUTH_KEYS = ("values", "effects")
OPTIONAL_KEYS = ("generator", "seed_offset", "nominal", "description")
BENCH_KEYS = {
    "actuator": {"gain", "delay", "natural_frequency", "damping"},
    "noise": None,           # channel -> one-sigma white noise [SI]
    "bandwidth": None,       # channel -> 2nd-order Butterworth corner [Hz] (lab-1 shorthand)
    "sensors": None,         # channel -> {filter, order, corner, gain, offset, resolution}
    "temperature": {"start", "start_scatter", "drift", "scatter", "viscosity_per_K", "modulus_per_K"},
    "scatter": {"actuator_gain"},
    "precharge": {"offset", "scatter"},  # friction test: the gas fill's error (real = set + offset, x (1 + scatter N))
}
SENSOR_KEYS = {"filter", "order", "corner", "gain", "offset", "resolution"}
CHANNELS = ("displacement [m]", "force [N]", "rod acceleration [m/s^2]", "flow [m^3/s]", "dp [Pa]", "oil temperature [K]",
            "top mount deflection [m]")
TEMPERATURE_DEFAULTS = {"start": 0.0, "start_scatter": 0.0, "drift": 0.0, "scatter": 0.0,
                        "viscosity_per_K": -0.03, "modulus_per_K": -0.005}


class LabError(UserError):
    """A lab description (hidden sample) is invalid, or a lab run failed."""


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def load_sample(path: str | Path) -> dict:
    """Read and check a hidden-sample description (keys and value kinds;
    the design keys are checked against the nominal design by
    :func:`check_sample`). Raises LabError naming the file and the key."""
    path = Path(path)
    if not path.is_file():
        raise LabError(f"{path}: sample file not found")
    try:
        doc = yaml_load_file(path)
    except ConfigTextError as e:
        raise LabError(str(e)) from None
    if not isinstance(doc, dict):
        raise LabError(f"{path}: expected a mapping with the keys {', '.join(REQUIRED_KEYS)}")
    if doc.get("generator") == LAB3_VERSION:
        return _load_sample3(path, doc)
    bad = _key_problems(doc, REQUIRED_KEYS)
    if bad:
        raise LabError(f"{path}: " + "; ".join(bad))
    if doc.get("generator", LAB_VERSION) not in ("dampertwin-lab 1", LAB_VERSION):
        bad.append(f"generator: {doc['generator']!r}; expected {LAB_VERSION!r}")
    if not isinstance(doc.get("seed_offset", 0), int) or isinstance(doc.get("seed_offset", 0), bool):
        bad.append(f"seed_offset: {doc['seed_offset']!r}; expected an integer")
    if "nominal" in doc and not isinstance(doc["nominal"], str):
        bad.append("nominal: expected a path (relative to the sample file) of a design YAML")
    for k, f in doc["factors"].items():
        if not (_finite(f) and f > 0):
            bad.append(f"factors.{k}: {f!r}; expected a positive finite factor")
    for k, v in doc["values"].items():
        if not _finite(v):
            bad.append(f"values.{k}: {v!r}; expected a finite number (SI)")
    for k, v in doc["effects"].items():
        if not isinstance(v, bool):
            bad.append(f"effects.{k}: {v!r}; expected true or false")
    return _finish_sample(path, doc, bad)


def _key_problems(doc: dict, required: tuple) -> list[str]:
    """Unknown top-level keys, and required sections missing or not mappings."""
    known = tuple(required) + tuple(OPTIONAL_KEYS)
    bad = [f"{k}: unknown key; expected {', '.join(known)}" for k in doc if k not in known]
    for k in required:
        if k not in doc:
            bad.append(f"{k}: missing")
        elif not isinstance(doc[k], dict):
            bad.append(f"{k}: expected a mapping")
    return bad


def _finish_sample(path: Path, doc: dict, bad: list[str]) -> dict:
    """Both generations: the benches checked, every problem raised at once
    naming the file, then the sample's path and content hash recorded."""
    bad += _check_benches(doc["benches"])
    if bad:
        raise LabError(f"{path}: " + "; ".join(bad))
    doc.setdefault("seed_offset", 0)
    doc["_path"] = str(path)
    doc["_hash"] = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    return doc


def _load_sample3(path: Path, doc: dict) -> dict:
    """A lab-3 sample: the truth's values and effects, the benches."""
    from .truth.params import TruthParameterError, check_effects, check_values

    bad = _key_problems(doc, REQUIRED_KEYS_3)
    if bad:
        raise LabError(f"{path}: " + "; ".join(bad))
    t = doc["truth"]
    bad += [f"truth.{k}: unknown key; expected {', '.join(TRUTH_KEYS)}" for k in t if k not in TRUTH_KEYS]
    for k in TRUTH_KEYS:
        if not isinstance(t.get(k, {}), dict):
            bad.append(f"truth.{k}: expected a mapping")
    if not bad:
        for check, sect in ((check_values, "values"), (check_effects, "effects")):
            try:
                check(t.get(sect, {}), f"truth.{sect}")
            except TruthParameterError as e:
                bad.append(str(e))
        bad += [f"truth.values.{k}: {v!r}; expected a finite number (SI)" for k, v in t.get("values", {}).items()
                if not _finite(v)]
    if not isinstance(doc.get("seed_offset", 0), int) or isinstance(doc.get("seed_offset", 0), bool):
        bad.append(f"seed_offset: {doc['seed_offset']!r}; expected an integer")
    return _finish_sample(path, doc, bad)


def is_truth_sample(sample: dict) -> bool:
    """A lab-3 sample: measured on dampertwin.truth."""
    return sample.get("generator") == LAB3_VERSION


def truth_part(design: Design, nominal: Design, sample: dict, P0: float | None = None):
    """(parameters, rest) of the truth behind a design case of a lab-3 sample,
    as built (per sample)."""
    from .truth.params import as_built_seed
    from .truth.part import build

    p, rest, _ = build(design, nominal, sample["truth"], as_built_seed(sample["seed_offset"]), P0=P0,
                       where=f"{sample.get('_path', '<sample>')}: truth")
    return p, rest


def _check_benches(b: dict) -> list[str]:
    bad = []
    for k, v in b.items():
        if k not in BENCH_KEYS:
            bad.append(f"benches.{k}: unknown key; expected {', '.join(BENCH_KEYS)}")
        elif not isinstance(v, dict):
            bad.append(f"benches.{k}: expected a mapping")
        elif BENCH_KEYS[k] is not None:
            bad += [f"benches.{k}.{q}: unknown key; expected {', '.join(sorted(BENCH_KEYS[k]))}"
                    for q in v if q not in BENCH_KEYS[k]]
            bad += [f"benches.{k}.{q}: {x!r}; expected a finite number" for q, x in v.items() if not _finite(x)]
    if bad:
        return bad
    for k in ("actuator", "noise"):
        if k not in b:
            bad.append(f"benches.{k}: missing")
    a = b.get("actuator", {})
    for q in ("gain", "delay"):
        if q not in a:
            bad.append(f"benches.actuator.{q}: missing")
    if a.get("gain", 1.0) <= 0 or a.get("delay", 0.0) < 0:
        bad.append("benches.actuator: gain must be > 0 and delay >= 0")
    if ("natural_frequency" in a) != ("damping" in a):
        bad.append("benches.actuator: natural_frequency [Hz] and damping [-] go together")
    if a.get("natural_frequency", 1.0) <= 0 or a.get("damping", 1.0) <= 0:
        bad.append("benches.actuator: natural_frequency and damping must be > 0")
    for sect in ("noise", "bandwidth"):
        for ch, v in b.get(sect, {}).items():
            if ch not in CHANNELS:
                bad.append(f"benches.{sect}.{ch}: unknown channel; expected {', '.join(CHANNELS)}")
            elif not (_finite(v) and v >= (0 if sect == "noise" else 1e-300)):
                bad.append(f"benches.{sect}.{ch}: {v!r}; expected a {'non-negative' if sect == 'noise' else 'positive'} number")
    for ch in set(b.get("bandwidth", {})) & set(b.get("sensors", {})):
        bad.append(f"benches.bandwidth.{ch} and benches.sensors.{ch} both describe the channel; expected one")
    for ch, spec in b.get("sensors", {}).items():
        where = f"benches.sensors.{ch}"
        if ch not in CHANNELS:
            bad.append(f"{where}: unknown channel; expected {', '.join(CHANNELS)}")
            continue
        if not isinstance(spec, dict):
            bad.append(f"{where}: expected a mapping of {', '.join(sorted(SENSOR_KEYS))}")
            continue
        bad += [f"{where}.{q}: unknown key; expected {', '.join(sorted(SENSOR_KEYS))}" for q in spec if q not in SENSOR_KEYS]
        if spec.get("filter", "none") not in FILTERS:
            bad.append(f"{where}.filter: {spec['filter']!r}; expected one of {', '.join(FILTERS)}")
        if spec.get("filter", "none") != "none":
            if not (_finite(spec.get("corner")) and spec["corner"] > 0):
                bad.append(f"{where}.corner: expected a positive corner frequency [Hz]")
            o = spec.get("order", 2)
            if not (isinstance(o, int) and not isinstance(o, bool) and 1 <= o <= 8):
                bad.append(f"{where}.order: {o!r}; expected an integer 1..8")
        for q in ("gain", "offset", "resolution"):
            if q in spec and not _finite(spec[q]):
                bad.append(f"{where}.{q}: {spec[q]!r}; expected a finite number")
        if spec.get("gain", 1.0) <= 0 or spec.get("resolution", 0.0) < 0:
            bad.append(f"{where}: gain must be > 0 and resolution >= 0")
    t = b.get("temperature", {})
    if any(t.get(q, 0.0) < 0 for q in ("start_scatter", "scatter")):
        bad.append("benches.temperature: start_scatter and scatter are one-sigma values >= 0")
    pf = b.get("precharge", {})
    if not all(_finite(v) for v in pf.values()) or pf.get("scatter", 0.0) < 0:
        bad.append("benches.precharge: offset [Pa] finite, scatter a one-sigma relative value >= 0")
    if b.get("scatter", {}).get("actuator_gain", 0.0) < 0:
        bad.append("benches.scatter.actuator_gain: one-sigma relative value >= 0")
    return bad


def sample_design(nominal: Design, sample: dict) -> Design:
    """The real part behind a nominal design: factors and absolute values."""
    ov = {k: nominal[k] * f for k, f in sample["factors"].items()}
    ov.update(sample["values"])
    ov.update({f"effects.{k}": bool(v) for k, v in sample["effects"].items()})
    return nominal.with_overrides(ov)


def check_sample(sample: dict, nominal: Design) -> None:
    """Every key of the sample names a design key, every effect a known
    switch, and the real part is a valid design (LabError naming the file)."""
    where = sample.get("_path", "<sample>")
    if is_truth_sample(sample):
        from .truth.params import TruthParameterError

        try:
            truth_part(nominal, nominal, sample)
        except (TruthParameterError, KeyError, ValueError, np.linalg.LinAlgError) as e:
            raise LabError(f"{where}: the truth's part is not valid: {e}") from None
        return
    bad = []
    for k in sample["effects"]:
        if k not in nominal.effects:
            bad.append(f"effects.{k}: unknown effect; expected one of {', '.join(sorted(nominal.effects))}")
    for sect in ("factors", "values"):
        for k in sample[sect]:
            try:
                v = nominal[k]
            except (KeyError, ValueError, TypeError):
                bad.append(f"{sect}.{k}: unknown design key")
                continue
            if not _finite(v):
                bad.append(f"{sect}.{k}: not a scalar design value")
    if bad:
        raise LabError(f"{where}: " + "; ".join(bad))
    try:
        sample_design(nominal, sample)
    except (DesignError, KeyError, ValueError) as e:
        raise LabError(f"{where}: the real part is not a valid design: {e}") from None


RECORDED = {"valve": ("flow [m^3/s]", "dp [Pa]"), "damper": ("displacement [m]", "force [N]", TEMPERATURE),
            "topmount": ("displacement [m]", "force [N]"),
            "module": ("displacement [m]", "force [N]", "rod acceleration [m/s^2]")}


def check_corners(sample: dict, protocols: dict) -> None:
    """Every transducer corner of the sample's benches at most the Nyquist
    frequency (rate / 2) of the fastest test recording its channel: a corner
    above it would never act on a record (the lab skips such a filter), so the
    sample would not describe the bench it claims. LabError naming file and key."""
    fastest: dict[str, tuple[float, str]] = {}
    for name, pc in protocols.items():
        for r in build_runs(pc, 0):
            for ch in RECORDED.get(r.configuration, ()):
                if r.rate > fastest.get(ch, (0.0, ""))[0]:
                    fastest[ch] = (float(r.rate), name)
    bad = []
    for key, spec in _sensor_specs(sample["benches"]).items():
        corner = spec.get("corner") if spec.get("filter", "none") != "none" else None
        if corner is None or key not in fastest:
            continue
        rate, test = fastest[key]
        if not corner <= rate / 2:
            sect = "sensors" if key in sample["benches"].get("sensors", {}) else "bandwidth"
            bad.append(f"benches.{sect}.{key}{'.corner' if sect == 'sensors' else ''}: {corner:g} Hz above "
                       f"the Nyquist frequency {rate / 2:g} Hz of the fastest test recording it ({test}, {rate:g} Hz)")
    if bad:
        raise LabError(f"{sample.get('_path', '<sample>')}: " + "; ".join(bad))


def _seed(root: int, sample: dict, *names: str) -> int:
    return int(root + sample["seed_offset"] + zlib.crc32("/".join(names).encode())) % (2**32)


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


def _sensor_specs(benches: dict) -> dict:
    """Channel -> real transducer description (lab-1 ``bandwidth`` shorthand:
    2nd-order Butterworth, no gain / offset error)."""
    specs = {ch: {"filter": "butter", "order": 2, "corner": fc} for ch, fc in benches.get("bandwidth", {}).items()}
    specs.update(benches.get("sensors", {}))
    return specs


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
    if run.configuration == "valve":
        cols["flow [m^3/s]"] = meas("flow [m^3/s]", r["flow [m^3/s]"])
        cols["dp [Pa]"] = meas("dp [Pa]", r["dp [Pa]"])
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


def plan(conf: Path, protocols: dict | None = None,
         architecture: str = DEFAULT_ARCHITECTURE) -> list[tuple[str, str]]:
    """(test, case) of every file the lab writes: the standard tests of
    approach 1 and, when ``conf/test`` declares them, the approach-2 tests
    the warm-up test ``thermal`` and the friction test ``friction`` (all their
    runs in one file, case ``baseline``). A passive ``architecture``: the
    flow bench of its valves, the compliance and curving tests and, when
    ``conf/test`` declares it, the dyno test (at 0 A)."""
    if architecture != DEFAULT_ARCHITECTURE:
        protocols = load_all(conf / "test") if protocols is None else protocols
        return ([("flowbench", v) for v in PASSIVE_VALVES[architecture]]
                + [(t, "baseline") for t in ("compliance", "curving", "dyno") if t in protocols])
    variants = load_variants(conf / "variant")
    protocols = load_all(conf / "test") if protocols is None else protocols
    items = [("flowbench", v) for v in VALVE_DESIGNS] + [("compliance", "baseline")]
    items += [("topmount", t) for t in TOP_MOUNTS] + [("curving", "baseline")]
    items += [("monosine", v.case) for v in variants] + [("random", v.case) for v in variants]
    items += [(t, "baseline") for t in APPROACH2_TESTS + EXTRA_TESTS if t in protocols]
    return items


def _sequence_temperatures(runs: list[Run], tc: dict, rng: np.random.Generator) -> list[float]:
    """Oil temperature rise [K] of each run of a test sequence: a start offset
    (another day, another oil state), a slow drift with test time (``drift``
    K/min, runs separated by REST_S) and a run-to-run scatter."""
    t0 = tc["start"] + tc["start_scatter"] * rng.standard_normal()
    out, clock = [], 0.0
    for r in runs:
        out.append(float(t0 + tc["drift"] * clock / 60.0 + tc["scatter"] * rng.standard_normal()))
        clock += r.excitation.t_end - r.excitation.t0 + REST_S
    return out


def measure_case(conf: Path, sample: dict, nominal: Design, protocol: str, case: str, seed: int,
                 protocols: dict | None = None, variants: dict | None = None) -> tuple[pd.DataFrame, dict]:
    """One (test, case) of the plan on the hidden sample: the frame and its
    metadata (without writing)."""
    protocols = load_all(conf / "test") if protocols is None else protocols
    variants = {v.case: v for v in load_variants(conf / "variant")} if variants is None else variants
    arch = getattr(nominal, "architecture", DEFAULT_ARCHITECTURE)
    if arch != DEFAULT_ARCHITECTURE and (protocol, case) not in plan(conf, protocols, arch):
        raise LabError(f"{sample.get('_path', '<sample>')}: test {protocol}/{case} is not one a {arch} damper can "
                       f"run; expected one of {', '.join('/'.join(i) for i in plan(conf, protocols, arch))}")
    s = _seed(seed, sample, protocol, case)
    rng = np.random.default_rng(s)
    pc = protocols[protocol]
    runs = build_runs(pc, seed)
    bench = None
    extra = {}
    if protocol == "flowbench":
        valve, vcase = VALVE_DESIGNS[case]
        d = variants[vcase].apply(nominal) if vcase else nominal
        runs = [next(r for r in runs if r.bench_valve == valve)]
        bench = flow_bench(pc)
        extra = {"valve": valve, "valve_design": case}
    elif protocol == "topmount":
        vcase = TOP_MOUNTS[case]
        d = variants[vcase].apply(nominal) if vcase else nominal
    elif protocol in ("compliance", "curving", "dyno") or protocol in APPROACH2_TESTS + EXTRA_TESTS:
        d = nominal
    else:
        v: Variant = variants[case]
        d = v.apply(nominal)
        runs = [r for r in runs if math.isclose(r.current, v.current)]
        if not runs:
            raise LabError(f"protocol {protocol} has no run at {v.current} A for case {case}")
    if arch != DEFAULT_ARCHITECTURE and protocol != "flowbench":
        runs = passive_runs(runs)
        extra = {**extra, "architecture": arch}
    b = sample["benches"]
    tc = {**TEMPERATURE_DEFAULTS, **b.get("temperature", {})}
    temps = _sequence_temperatures(runs, tc, rng) if protocol != "topmount" else [0.0] * len(runs)
    sg = b.get("scatter", {}).get("actuator_gain", 0.0)
    gains = [1.0 + sg * rng.standard_normal() for _ in runs]
    thermo = "temperature" in pc.get("sensors", {})
    lvdt = "deflection" in pc.get("sensors", {})
    frames = [record(r, d, sample, rng, bench, oil_dT=dT, gain_scatter=g, temperature=thermo, nominal=nominal,
                     deflection=lvdt) for r, dT, g in zip(runs, temps, gains)]
    truth = {}
    if is_truth_sample(sample):
        from .truth import TRUTH_VERSION
        from .truth.run import ATOL, RTOL

        truth = {"truth": TRUTH_VERSION, "truth_rtol": RTOL, "truth_atol": ATOL,
                 "note": "SYNTHETIC measurement from the dampertwin virtual laboratory: hidden sample on the "
                         f"reference damper {TRUTH_VERSION} (other physics than the model)"}
    meta = {"synthetic": True, "generator": LAB3_VERSION if truth else LAB_VERSION, "dampertwin": __version__,
            "seed": s,
            "design_hash": d.hash(), "protocol": protocol, "case": case,
            "sample": Path(sample.get("_path", "sample.yaml")).name, "sample_hash": sample.get("_hash", ""),
            "truth_rtol": TRUTH_RTOL, "truth_atol": TRUTH_ATOL,
            "oil_temperature_K": {r.name: round(d["oil.T"] + dT, 3) for r, dT in zip(runs, temps)},
            "note": "SYNTHETIC measurement from the dampertwin virtual laboratory (hidden sample)", **extra, **truth}
    return pd.concat(frames, ignore_index=True), meta


def _measure_and_write(conf: str, sample: dict, nominal_path: str, protocol: str, case: str, seed: int,
                       out: str) -> str:
    nominal = load_design(nominal_path)
    df, meta = measure_case(Path(conf), sample, nominal, protocol, case, seed)
    return str(write_frame(Path(out) / protocol / f"{case}.parquet", df, meta))


def _nominal_path(conf: Path, sample: dict) -> Path:
    if "nominal" in sample:
        return (Path(sample["_path"]).parent / sample["nominal"]).resolve()
    return conf / "lab" / "nominal.yaml"


def run_lab(sample: str | Path, out: str | Path, tests: list[str] | None = None, seed: int = 0,
            progress: bool = True, conf: str | Path | None = None, only: list[tuple[str, str]] | None = None,
            workers: int | None = None) -> list[Path]:
    """Run a hidden-sample file through the standard tests (all, or the
    ``tests`` named) and write ``out/<test>/<case>.parquet``, labelled
    synthetic. ``conf`` is the configuration folder (protocols, variants;
    default the project's); ``workers`` processes run the cases in parallel
    (default: the machine's cores). Same sample, seed and conf: same bytes."""
    from .progress import progress as tqdm

    from .config import repo_root

    conf = Path(conf) if conf is not None else repo_root(Path(__file__).parent) / "conf"
    sample_doc = load_sample(sample)
    nominal_path = _nominal_path(conf, sample_doc)
    try:
        nominal = load_design(nominal_path)
    except (DesignError, FileNotFoundError) as e:
        raise LabError(f"{sample}: nominal design {nominal_path}: {e}") from None
    check_sample(sample_doc, nominal)
    protocols = load_all(conf / "test")
    check_corners(sample_doc, protocols)
    items = plan(conf, protocols, getattr(nominal, "architecture", DEFAULT_ARCHITECTURE)) if only is None else list(only)
    if tests is not None:
        known = sorted({t for t, _ in items})
        unknown = [t for t in tests if t not in known]
        if unknown:
            raise LabError(f"--tests: unknown test(s) {', '.join(unknown)}; expected some of {', '.join(known)}")
        items = [it for it in items if it[0] in tests]
    out = Path(out)
    # longest first (module random tests), so the workers finish together
    order = sorted(range(len(items)), key=lambda i: items[i][0] not in ("random", "verification", "training"))
    workers = min(len(items), workers or os.cpu_count() or 1)
    args = [(str(conf), sample_doc, str(nominal_path), *items[i], seed, str(out)) for i in order]
    paths: dict[int, str] = {}
    bar = tqdm(total=len(items), desc="lab", disable=not progress)
    if workers <= 1:
        for i, a in zip(order, args):
            paths[i] = _measure_and_write(*a)
            bar.update()
    else:
        with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
            futs = {pool.submit(_measure_and_write, *a): i for i, a in zip(order, args)}
            for f in as_completed(futs):
                paths[futs[f]] = f.result()
                bar.update()
    bar.close()
    return [Path(paths[i]) for i in range(len(items))]


def generate(conf: str | Path, out: str | Path, seed: int, only: list[tuple[str, str]] | None = None,
             progress: bool = True, sample: str | Path | None = None, workers: int | None = None) -> list[Path]:
    """The DVC lab stage: ``conf/lab/<STAGE_SAMPLE>`` (or ``sample``) through
    every test of the plan into ``out`` (data/measured)."""
    conf = Path(conf)
    return run_lab(sample or conf / "lab" / STAGE_SAMPLE, out, seed=seed, progress=progress, conf=conf,
                   only=only, workers=workers)
