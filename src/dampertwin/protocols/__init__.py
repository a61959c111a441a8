"""Standard test protocols (thesis 2.7, 6.2-6.5, 7.2), declared in
``conf/test/*.yaml`` and turned into runs: an excitation, the configuration,
the active-valve current and the recording rate.

``load_protocol(path)`` validates a file (one ProtocolError listing every
problem with the file and key); ``build_runs(protocol, seed)`` makes the runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

from ..design import ConfigTextError, yaml_load_file
from ..excitation import Excitation
from ..model.layout import VALVE_NAMES
from ..errors import UserError
from .signals import DYNO_REST, band_noise, sine_burst_train, triangle_ramps, triangle_wave, velocity_steps

EXCITATION_RATE = 20_000.0  # [Hz] sampling of generated excitations


class ProtocolError(UserError):
    def __init__(self, errors: list[str]):
        self.errors = list(errors)
        ValueError.__init__(self, "invalid test protocol:\n  - " + "\n  - ".join(self.errors))


@dataclass(frozen=True)
class Run:
    """One simulated / measured record of a test."""

    test: str
    name: str
    configuration: str
    excitation: Excitation
    current: float
    rate: float
    bench_valve: str | None = None
    meta: dict = field(default_factory=dict)


# ------------------------------------------------------------ validation
_SCHEMA: dict[str, dict[str, Any]] = {
    "flowbench": {"configuration": "valve", "valves": dict, "ramp_time": float, "cycles": int, "rate": float,
                  "back_pressure": float, "volume": float},
    "activevalve": {"configuration": "active_valve", "currents": list, "dp_max": float, "ramp_time": float,
                    "cycles": int, "rate": float, "back_pressure": float},
    "compliance": {"configuration": "damper", "amplitude": float, "velocities": list, "cycles": int,
                   "current": float, "rate": float},
    "topmount": {"configuration": "topmount", "static": dict, "random": dict, "sweep": dict, "rate": float},
    "curving": {"configuration": "damper", "amplitude": float, "velocities": list, "currents": list,
                "cycles": int, "rate": float},
    "monosine": {"configuration": "module", "amplitude": float, "frequency": float, "cycles": int,
                 "currents": list, "rate": float},
    "random": {"configuration": "module", "duration": float, "bands": list, "currents": list,
               "seed_offset": int, "rate": float},
    "training": {"configuration": ("damper", "module"), "strokes": list, "velocities": list, "cycles": int,
                 "currents": list, "rate": float},
    "verification": {"configuration": ("damper", "module"), "duration": float, "bands": list,
                     "currents": list, "seed_offset": int, "rate": float},
    "thermal": {"configuration": "damper", "amplitude": float, "frequency": float, "duration": float,
                "currents": list, "rate": float},
    "friction": {"configuration": "damper", "amplitude": float, "velocity": float, "currents": list,
                 "precharges": list, "cycles": int, "rate": float},
    "dyno": {"configuration": "damper", "amplitude": float, "velocities": list, "waveform": str, "cycles": int,
             "rate": float},
}
# keys a protocol may leave out (validated when given); a protocol without currents is passive (one run)
_OPTIONAL: dict[str, dict[str, Any]] = {"dyno": {"currents": list, "rest": float}}
_CHOICES = {"waveform": ("sine", "triangle")}  # str keys: their allowed values
DYNO_MIN_CYCLES = {"sine": 4, "triangle": 3}  # the KPIs need 2 half-strokes per direction after the run-in
# (a sine burst also spends a period fading in and one fading out)
# documented bandwidths [Hz] a protocol may name; deflection: the module test's LVDT on the rod (thesis 7.2)
SENSOR_KEYS = ("force", "acceleration", "temperature", "deflection")
PROTOCOLS = tuple(_SCHEMA)
# Physical plausibility: a unit mix-up (mm written as m, mm/s as m/s) or a sampling too coarse for the test is
# refused by the loader, naming the file and key (``simulate`` also checks a run against the design's own travel)
MAX_AMPLITUDE = 0.2  # [m] displacement from mid-stroke (an amplitude, half a stroke, 4 rms of noise): above any
# road-vehicle damper's travel (conf/design/baseline.yaml: a ~240 mm stroke), 25x below 5 mm written as 5 m
MAX_VELOCITY = 10.0  # [m/s] peak rod velocity: a road damper sees < ~5 m/s; a mm/s figure written as m/s is 1000x
SAMPLES_PER_PERIOD = 20  # recorded samples per period of a periodic excitation's highest frequency (a peak
# is caught within 1 - cos(pi / 20) = 1.2 %)
NOISE_RATE_RATIO = 2.56  # recording rate / highest band edge of a noise excitation (the spectrum analysers'
# ratio: the whole band below the Nyquist frequency, with the anti-alias filter's margin)
_AMPLITUDE_KEY = {"monosine", "thermal", "compliance", "curving", "friction", "dyno"}  # protocols with `amplitude`


def validate(doc: Any, where: str) -> dict:
    """Check a protocol document; raise ProtocolError naming file and key."""
    if not isinstance(doc, dict):
        raise ProtocolError([f"{where}: expected a mapping with a 'protocol' key"])
    name = doc.get("protocol")
    if name not in _SCHEMA:
        raise ProtocolError([f"{where}: unknown protocol {name!r}; expected one of {', '.join(PROTOCOLS)}"])
    errors = []
    optional = _OPTIONAL.get(name, {})
    for key, kind in {**_SCHEMA[name], **optional}.items():
        if key not in doc:
            if key not in optional:
                errors.append(f"{where}: {name}.{key} missing")
            continue
        v = doc[key]
        if key == "configuration":
            allowed = kind if isinstance(kind, tuple) else (kind,)
            if v not in allowed:
                errors.append(f"{where}: {name}.configuration {v!r}; expected {' or '.join(allowed)}")
        elif kind is float:
            if not _pos(v):
                errors.append(f"{where}: {name}.{key} = {v!r}; expected a positive finite number (SI)")
        elif kind is int:
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= (0 if key == "seed_offset" else 1)):
                errors.append(f"{where}: {name}.{key} = {v!r}; expected a positive integer")
        elif kind is list:
            if not isinstance(v, list) or not v:
                errors.append(f"{where}: {name}.{key} must be a non-empty list")
            elif key != "bands" and not all(_pos(x) for x in v):
                errors.append(f"{where}: {name}.{key} = {v!r}; expected positive finite numbers (SI)")
        elif kind is dict and not isinstance(v, dict):
            errors.append(f"{where}: {name}.{key} must be a mapping")
        elif kind is str and v not in _CHOICES[key]:
            errors.append(f"{where}: {name}.{key} = {v!r}; expected {' or '.join(_CHOICES[key])}")
    sensors = doc.get("sensors", {})
    if not isinstance(sensors, dict) or any(k not in SENSOR_KEYS or not _pos(v) for k, v in sensors.items()):
        errors.append(f"{where}: {name}.sensors must map {' / '.join(SENSOR_KEYS)} to a bandwidth in Hz, "
                      f"got {sensors!r}")
    if name == "thermal" and not (isinstance(sensors, dict) and "temperature" in sensors):
        errors.append(f"{where}: thermal.sensors.temperature missing (the thermocouple's documented bandwidth in Hz)")
    for k in doc:
        if k not in ("protocol", "sensors") and k not in _SCHEMA[name] and k not in optional:
            errors.append(f"{where}: {name}.{k}: unknown key; expected {', '.join([*_SCHEMA[name], *optional])}")
    for key in ("bands",):
        for i, b in enumerate(doc.get(key, []) if isinstance(doc.get(key), list) else []):
            if not _band_ok(b):
                errors.append(f"{where}: {name}.bands[{i}] must be {{band: [f_lo, f_hi] Hz, rms: m}}, got {b!r}")
    if name == "flowbench" and isinstance(doc.get("valves"), dict):
        for k, v in doc["valves"].items():
            if k not in VALVE_NAMES:
                errors.append(f"{where}: flowbench.valves.{k}: unknown valve; expected {', '.join(VALVE_NAMES)}")
            elif not (isinstance(v, dict) and _pos(v.get("q_max"))):
                errors.append(f"{where}: flowbench.valves.{k}.q_max must be a positive flow in m^3/s")
    if name == "dyno" and doc.get("waveform") in DYNO_MIN_CYCLES and isinstance(doc.get("cycles"), int):
        need = DYNO_MIN_CYCLES[doc["waveform"]]
        if doc["cycles"] < need:
            errors.append(f"{where}: dyno.cycles = {doc['cycles']}; a {doc['waveform']} step needs >= {need} "
                          f"(steady cycles between the run-in and the run-out)")
    if not errors:  # every value of the right type: their magnitudes
        errors += _implausible(name, doc, where)
    if errors:
        raise ProtocolError(errors)
    return doc


def _highest_frequency(name: str, c: dict) -> tuple[float, str] | None:
    """The highest frequency [Hz] of a periodic excitation of the protocol and what sets it; None for noise."""
    if name in ("monosine", "thermal"):
        return c["frequency"], f"{name}.frequency"
    if name in ("compliance", "curving", "dyno"):
        per = 4.0 if c.get("waveform") == "triangle" else 2 * math.pi  # a triangle's period is 4 A / v
        return max(c["velocities"]) / (per * c["amplitude"]), f"{name}.velocities / amplitude"
    if name == "friction":
        return c["velocity"] / (2 * math.pi * c["amplitude"]), "friction.velocity / amplitude"
    if name == "training":
        return max(c["velocities"]) / (math.pi * min(c["strokes"])), "training.velocities / strokes"
    if name in ("flowbench", "activevalve"):
        return 1.0 / (2.0 * c["ramp_time"]), f"{name}.ramp_time"
    return None


def _implausible(name: str, c: dict, where: str) -> list[str]:
    """Values of a well-typed protocol outside what a damper test can be (MAX_AMPLITUDE, MAX_VELOCITY) or
    sampled too coarsely for its excitation (SAMPLES_PER_PERIOD, NOISE_RATE_RATIO). Returns the problems."""
    errors = []
    mix = "expected SI metres (mm written as m?)"
    amps = {f"{name}.amplitude": c["amplitude"]} if name in _AMPLITUDE_KEY else {}
    if name == "training":
        amps[f"{name}.strokes (peak-to-peak) / 2"] = max(c["strokes"]) / 2
    tm = c if name == "topmount" else {}
    st, sw, rnd = (tm.get(k) if isinstance(tm.get(k), dict) else {} for k in ("static", "sweep", "random"))
    if _pos(st.get("amplitude")):
        amps["topmount.static.amplitude"] = st["amplitude"]
    if isinstance(sw.get("amplitudes"), list) and all(_pos(a) for a in sw["amplitudes"]) and sw["amplitudes"]:
        amps["topmount.sweep.amplitudes"] = max(sw["amplitudes"])
    bands = c.get("bands") or rnd.get("bands")
    bands = bands if isinstance(bands, list) and bands and all(_band_ok(b) for b in bands) else None
    bands_key = f"{name}.bands" if "bands" in c else "topmount.random.bands"
    if bands:
        amps[f"{bands_key} (4 x the total rms)"] = 4 * math.sqrt(sum(b["rms"] ** 2 for b in bands))
    for key, a in amps.items():
        if a > MAX_AMPLITUDE:
            errors.append(f"{where}: {key} = {a:g} m; above {MAX_AMPLITUDE:g} m from mid-stroke, more than a "
                          f"damper's travel: {mix}")
    vels = {f"{name}.velocities": max(c["velocities"])} if isinstance(c.get("velocities"), list) else {}
    if name == "friction":
        vels["friction.velocity"] = c["velocity"]
    if name in ("monosine", "thermal") and c["amplitude"] <= MAX_AMPLITUDE:  # else the amplitude is the error
        vels[f"{name}.frequency x amplitude (2 pi f A)"] = 2 * math.pi * c["frequency"] * c["amplitude"]
    for key, v in vels.items():
        if v > MAX_VELOCITY:
            errors.append(f"{where}: {key} = {v:g} m/s peak; above {MAX_VELOCITY:g} m/s, faster than a road damper "
                          f"moves: expected SI m/s (mm/s written as m/s? mm as m?)")
    hf = _highest_frequency(name, c)
    rates = [(f"{name}.rate", c["rate"], hf)]
    if _pos(st.get("rate")) and _pos(st.get("period")):
        rates.append(("topmount.static.rate", st["rate"], (1.0 / st["period"], "topmount.static.period")))
    for key, rate, (f, what) in [r for r in rates if r[2] is not None]:
        if rate < SAMPLES_PER_PERIOD * f:
            errors.append(f"{where}: {key} = {rate:g} Hz; {what} makes a {f:.4g} Hz excitation, which needs >= "
                          f"{SAMPLES_PER_PERIOD * f:.4g} Hz ({SAMPLES_PER_PERIOD} samples per period)")
    if bands:
        f = max(b["band"][1] for b in bands)
        if c["rate"] < NOISE_RATE_RATIO * f:
            errors.append(f"{where}: {name}.rate = {c['rate']:g} Hz; {bands_key} reach {f:g} Hz, which needs >= "
                          f"{NOISE_RATE_RATIO * f:g} Hz ({NOISE_RATE_RATIO:g} x the highest band edge)")
    return errors


def _band_ok(b) -> bool:
    """A noise band ``{band: [f_lo, f_hi] Hz, rms: m}``."""
    return (isinstance(b, dict) and isinstance(b.get("band"), list) and len(b["band"]) == 2
            and all(_pos(x) for x in b["band"]) and b["band"][0] < b["band"][1] and _pos(b.get("rms")))


def _pos(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0


def load_protocol(path: str | Path) -> dict:
    path = Path(path)
    if not path.is_file():
        raise ProtocolError([f"{path}: file not found"])
    try:
        doc = yaml_load_file(path)
    except ConfigTextError as e:
        raise ProtocolError([str(e)]) from None
    return validate(doc, str(path))


# ------------------------------------------------------------ builders
def flow_bench(c: dict) -> dict:
    """``simulate(..., bench=)`` of a flow-bench protocol: its volume [m^3]
    and back pressure [Pa] (the lab, the plots and the discrepancy workflow);
    of the active-valve bench: its back pressure."""
    if c["protocol"] == "activevalve":
        return {"bench_back_pressure": float(c["back_pressure"])}
    return {"bench_volume": float(c["volume"]), "bench_back_pressure": float(c["back_pressure"])}


def _flowbench(c, seed):
    runs = []
    for valve, v in c["valves"].items():
        ex = triangle_ramps(v["q_max"], c["ramp_time"], c["cycles"], sample_rate=1000.0)
        runs.append(Run("flowbench", valve, "valve", ex, 0.0, c["rate"], valve,
                        {"q_max [m^3/s]": v["q_max"], "ramp_time [s]": c["ramp_time"],
                         "back_pressure [Pa]": c["back_pressure"], "volume [m^3]": c["volume"]}))
    return runs


def _activevalve(c, seed):
    """Active-valve bench: per current, ``cycles`` triangles of the pressure drop 0 -> dp_max -> 0 [Pa]
    (a pressure-controlled bench; the flow through the valve is measured)."""
    runs = []
    for I in c["currents"]:
        ex = replace(triangle_ramps(c["dp_max"], c["ramp_time"], c["cycles"], sample_rate=1000.0), kind="pressure")
        runs.append(Run("activevalve", f"I{I:g}", "active_valve", ex, float(I), c["rate"], None,
                        {"dp_max [Pa]": c["dp_max"], "ramp_time [s]": c["ramp_time"],
                         "back_pressure [Pa]": c["back_pressure"]}))
    return runs


def _sines(test, c, currents, velocities, amplitude_of):
    runs = []
    for I in currents:
        for v in velocities:
            A = amplitude_of(v)
            f = v / (2 * math.pi * A)
            ex = Excitation.sine(A, f, c["cycles"] / f, sample_rate=max(EXCITATION_RATE, 200 * f))
            runs.append(Run(test, f"v{v:g}_I{I:g}", c["configuration"], ex, float(I), c["rate"], None,
                            {"velocity [m/s]": float(v), "amplitude [m]": A, "frequency [Hz]": f,
                             "cycles": c["cycles"]}))
    return runs


def _compliance(c, seed):
    return _sines("compliance", c, [c["current"]], c["velocities"], lambda v: c["amplitude"])


def _curving(c, seed):
    return _sines("curving", c, c["currents"], c["velocities"], lambda v: c["amplitude"])


def _monosine(c, seed):
    A, f = c["amplitude"], c["frequency"]
    return [Run("monosine", f"I{I:g}", "module", Excitation.sine(A, f, c["cycles"] / f), float(I), c["rate"], None,
                {"amplitude [m]": A, "frequency [Hz]": f, "cycles": c["cycles"]}) for I in c["currents"]]


def _noise_runs(test, c, seed):
    ex = band_noise(c["bands"], c["duration"], seed + c["seed_offset"], sample_rate=max(c["rate"], 2000.0))
    return [Run(test, f"I{I:g}", c["configuration"], ex, float(I), c["rate"], None,
                {"duration [s]": c["duration"], "seed": seed + c["seed_offset"]}) for I in c["currents"]]


def _random(c, seed):
    return _noise_runs("random", c, seed)


def _verification(c, seed):
    return _noise_runs("verification", c, seed)


def _training(c, seed):
    segments = [(s / 2, v) for s in c["strokes"] for v in c["velocities"]]
    ex = sine_burst_train(segments, c["cycles"])
    return [Run("training", f"I{I:g}", c["configuration"], ex, float(I), c["rate"], None,
                {"segments": len(segments)}) for I in c["currents"]]


def _thermal(c, seed):
    """Warm-up runs: one long sine per current (the oil heats by the dissipated power)."""
    A, f, T = c["amplitude"], c["frequency"], c["duration"]
    return [Run("thermal", f"I{I:g}", "damper", Excitation.sine(A, f, T), float(I), c["rate"], None,
                {"amplitude [m]": A, "frequency [Hz]": f, "duration [s]": T}) for I in c["currents"]]


def _friction(c, seed):
    """Slow sines per current at each gas precharge [Pa abs] (the reserve gas refilled between
    runs): the run's design has oil.P_0 = its precharge (``meta["precharge [Pa]"]``)."""
    A, v = c["amplitude"], c["velocity"]
    f = v / (2 * math.pi * A)
    return [Run("friction", f"P{P / 1e5:.3g}bar_I{I:g}", "damper", Excitation.sine(A, f, c["cycles"] / f), float(I),
                c["rate"], None, {"precharge [Pa]": float(P), "velocity [m/s]": float(v), "amplitude [m]": A,
                                  "frequency [Hz]": f, "cycles": c["cycles"]})
            for I in c["currents"] for P in c["precharges"]]


def _topmount(c, seed):
    st = c["static"]
    runs = [Run("topmount", "static", "topmount", triangle_wave(st["amplitude"], st["period"], st["cycles"]), 0.0,
                st["rate"], None, {"amplitude [m]": st["amplitude"], "period [s]": st["period"]})]
    r = c["random"]
    runs += [Run("topmount", "random", "topmount",
                band_noise(r["bands"], r["duration"], seed + r.get("seed_offset", 0), sample_rate=c["rate"]),
                0.0, c["rate"], None, {"duration [s]": r["duration"]})]
    s = c["sweep"]
    for A in s["amplitudes"]:
        for f in s["frequencies"]:
            if A >= s["large_amplitude"] and f > s["max_frequency_large"]:
                continue
            ex = Excitation.sine(A, f, s["cycles"] / f, sample_rate=max(EXCITATION_RATE, 200 * f))
            runs.append(Run("topmount", f"sweep_A{A:g}_f{f:g}", "topmount", ex, 0.0, max(c["rate"], 50 * f), None,
                            {"amplitude [m]": A, "frequency [Hz]": f, "cycles": s["cycles"]}))
    return runs


def _dyno(c, seed):
    """Dyno test: one stepped record per current (``currents``; none: one passive run at 0 A, for a
    passive architecture, which reads no current) of ``cycles`` cycles at each peak velocity in turn."""
    A, vs, wf = c["amplitude"], c["velocities"], c["waveform"]
    ex = velocity_steps(A, vs, c["cycles"], wf, c.get("rest", DYNO_REST))
    meta = {"amplitude [m]": A, "velocities [m/s]": [float(v) for v in vs], "waveform": wf, "cycles": c["cycles"]}
    if "currents" not in c:
        return [Run("dyno", "passive", "damper", ex, 0.0, c["rate"], None, {**meta, "passive": True})]
    return [Run("dyno", f"I{I:g}", "damper", ex, float(I), c["rate"], None, dict(meta)) for I in c["currents"]]


_BUILDERS: dict[str, Callable] = {
    "flowbench": _flowbench, "activevalve": _activevalve, "compliance": _compliance, "topmount": _topmount,
    "curving": _curving, "monosine": _monosine, "random": _random, "training": _training, "verification": _verification,
    "thermal": _thermal, "friction": _friction, "dyno": _dyno,
}


def build_runs(protocol: dict, seed: int = 0) -> list[Run]:
    """The runs of a validated protocol; random signals derive from ``seed``."""
    validate(protocol, f"<{protocol.get('protocol') if isinstance(protocol, dict) else protocol}>")
    return _BUILDERS[protocol["protocol"]](protocol, int(seed))


def passive_runs(runs: list[Run], *, at_zero: bool = False) -> list[Run]:
    """The runs of a test that a passive damper (no active valve: no current to read) runs. Runs that differ
    only by the active-valve current (same test, configuration, valve, rate, excitation and metadata) are one
    run for it: the first of them, at the protocol's first current; order kept. A protocol's single current-free
    run (the dyno test without ``currents:``, label ``passive``, 0 A) is kept as it is. ``at_zero``: the kept
    runs at 0 A, a current label ``_I<current>`` written ``_I0`` (the lab's records of a passive sample)."""
    seen: set = set()
    kept = []
    for r in runs:
        key = _input_key(r)
        if key not in seen:
            seen.add(key)
            kept.append(r)
    if at_zero:
        kept = [replace(r, current=0.0, name=(r.name.rsplit("_I", 1)[0] + "_I0") if "_I" in r.name else r.name)
                for r in kept]
    return kept


def _input_key(r: Run) -> tuple:
    """What a run feeds the damper, its current left out."""
    ex = r.excitation
    return (r.test, r.configuration, r.bench_valve, float(r.rate), ex.kind, float(ex.t0), float(ex.dt),
            ex.value.tobytes(), ex.rate.tobytes(), repr(sorted(r.meta.items())))


def recording_rates(protocol: dict) -> float | dict[str, float]:
    """The sampling rate [Hz] a record of the protocol is made at: one
    value, or per run label where runs differ (top mount: static 200 Hz,
    random and sweeps faster). For ``io.read_frame(..., rate=...)``."""
    rates = {r.name: float(r.rate) for r in build_runs(protocol, 0)}
    vals = set(rates.values())
    return vals.pop() if len(vals) == 1 else rates


def load_all(conf_dir: str | Path) -> dict[str, dict]:
    """Every protocol in ``conf_dir`` (conf/test), keyed by file stem (the
    test's name: ``monosine16.yaml`` is a second ``protocol: monosine`` test
    and must not replace ``monosine.yaml``)."""
    out = {}
    for f in sorted(Path(conf_dir).glob("*.yaml")):
        out[f.stem] = load_protocol(f)
    return out


__all__ = ["Run", "ProtocolError", "PROTOCOLS", "load_protocol", "validate", "build_runs", "load_all",
           "recording_rates", "passive_runs"]
