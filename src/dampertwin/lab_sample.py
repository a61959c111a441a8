"""The virtual laboratory's hidden samples (dampertwin.lab): reading and
checking a sample description (lab 2: the model's parameters; lab 3: the
truth's), its benches and transducers, and the real part behind a nominal
design. Problems raise LabError naming the file and the key."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np

from .design import ConfigTextError, Design, DesignError, yaml_load_file
from .errors import UserError
from .protocols import build_runs
from .sensors import FILTERS

LAB_VERSION = "dampertwin-lab 2"
LAB3_VERSION = "dampertwin-lab 3"  # the truth of other physics (dampertwin.truth)

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
TEMPERATURE = "oil temperature [K]"


# A real rig's plausible extremes: a value beyond one is a unit slip (ms for s, Pa for bar), not a rig the tests
# could run on (records the project's reader refuses, a solver that fails with no key named).
BENCH_LIMITS = {
    ("actuator", "gain"): (0.5, 2.0),            # [-] static gain of the position loop
    ("actuator", "delay"): (0.0, 0.05),          # [s] loop delay (servo-hydraulic rigs: ~1 ms)
    ("temperature", "start"): (-60.0, 120.0),    # [K] oil temperature above the design's oil.T at a run's start
    ("temperature", "drift"): (-10.0, 10.0),     # [K/min] over the test sequence
    ("precharge", "offset"): (-2.0e5, 2.0e5),    # [Pa] the gas fill's error (+-2 bar)
}
CHANNEL_NOISE_MAX = {  # [SI] one-sigma noise or ADC step of a usable transducer (~1 % of the tests' ranges)
    "displacement [m]": 1.0e-3, "force [N]": 500.0, "rod acceleration [m/s^2]": 50.0, "flow [m^3/s]": 1.0e-5,
    "dp [Pa]": 1.0e5, "oil temperature [K]": 5.0, "top mount deflection [m]": 1.0e-4,
}


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
    if "nominal" in doc and not isinstance(doc["nominal"], str):
        bad.append("nominal: expected a path (relative to the sample file) of a design YAML")
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
    return bad or _plausible_rig(b)


def _plausible_rig(b: dict) -> list[str]:
    """BENCH_LIMITS and CHANNEL_NOISE_MAX on a bench description whose keys and kinds are valid."""
    bad = []
    for (sect, q), (lo, hi) in BENCH_LIMITS.items():
        v = b.get(sect, {}).get(q)
        if v is not None and not lo <= v <= hi:
            bad.append(f"benches.{sect}.{q}: {v!r}; expected {lo:g} to {hi:g} (a real rig's range; a unit slip?)")
    levels = [(f"noise.{ch}", ch, v) for ch, v in b.get("noise", {}).items()]
    levels += [(f"sensors.{ch}.resolution", ch, spec["resolution"]) for ch, spec in b.get("sensors", {}).items()
               if "resolution" in spec]
    for where, ch, v in levels:
        if v > CHANNEL_NOISE_MAX[ch]:
            bad.append(f"benches.{where}: {v!r}; expected at most {CHANNEL_NOISE_MAX[ch]:g} (a usable transducer's "
                       f"noise / ADC step; a unit slip?)")
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


RECORDED = {"valve": ("flow [m^3/s]", "dp [Pa]"), "active_valve": ("flow [m^3/s]", "dp [Pa]"), "damper": ("displacement [m]", "force [N]", TEMPERATURE),
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


def _sensor_specs(benches: dict) -> dict:
    """Channel -> real transducer description (lab-1 ``bandwidth`` shorthand:
    2nd-order Butterworth, no gain / offset error)."""
    specs = {ch: {"filter": "butter", "order": 2, "corner": fc} for ch, fc in benches.get("bandwidth", {}).items()}
    specs.update(benches.get("sensors", {}))
    return specs
