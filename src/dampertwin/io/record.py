"""The one reader of measurement files: ``read_record`` is what ``fit``,
``import``, the stages and ``discrepancy`` call, so every entry point applies
the same checks to a record of a standard test (``conf/test/<test>.yaml``):

- the schema of :func:`dampertwin.io.check_frame` (SI columns, finite
  numbers, uniform and increasing time, a reversed time axis named as such,
  the protocol's sampling rate and minimum duration, no dead channel, an
  empty or oversized file refused);
- a ``run`` column whose labels are runs of the protocol (a compliance or
  friction record read as a top-mount record is refused), a file's metadata
  naming the same protocol, a flow-bench record's valve against the file name
  and the valve asked for;
- plausible magnitudes: each channel's peak against the protocol's target
  (displacement, flow) or a physical range (force, pressure, acceleration),
  a value ``PLAUSIBLE_FACTOR`` or more off refused, naming the column and the
  likely unit mix-up (mm under [m], l/min under [m^3/s], bar under [Pa], ...);
- the sign of the force: a damper, a top mount and a valve dissipate energy,
  so a record that generates it has its force (or pressure) sign flipped.

A record read without a test (a friction-device record for ``fit friction``)
uses the protocol its metadata names, else the generic checks: time, rate
within ``GENERIC_RATE``, dead channels, physical ranges, dissipation.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from . import MIN_RATE, DataError, check_frame, read_table

PLAUSIBLE_FACTOR = 30.0  # a channel's peak may lie up to this factor above / below the protocol's target
# physical range of a channel's peak |value| (SI) in any damper, top-mount or valve test; None: not bounded
PEAK_RANGE = {"displacement": (None, 1.0), "force": (1.0, 1.0e6), "dp": (1.0e4, 1.0e8), "flow": (None, 0.1),
              "rod acceleration": (None, 1.0e5), "velocity": (None, 100.0), "current": (None, 10.0)}
# a typical peak of each quantity (SI), only to name the likely unit of a value outside PEAK_RANGE
TYPICAL = {"displacement": 5e-3, "force": 1e3, "dp": 2e6, "flow": 1e-3, "rod acceleration": 100.0, "velocity": 0.5,
           "current": 1.0}
# samples and duration [s] a record read without a protocol needs at least (a few cycles of any bench excitation)
GENERIC_MIN = (100, 0.1)
VELOCITY_MIN_CORR = 0.9  # a velocity column's integral against the displacement (both detrended), at least
VELOCITY_MAX_GAIN = 1.5  # ... and its scale within this factor of 1 (a unit mix-up is a factor of 10 or more)
GENERIC_RATE = (100.0, 2.0e6)  # [Hz] sampling rate of a record read without a protocol (bench rigs record at >= 200 Hz)
SIGN_TOL = 0.05  # a record generating more than this fraction of its |F v| energy has a flipped sign
# common non-SI units a number may have been written in, per SI unit: (unit, factor to SI)
MIXUPS = {
    "m": (("mm", 1e-3), ("cm", 1e-2), ("um", 1e-6), ("in", 0.0254), ("km", 1e3)),
    "s": (("ms", 1e-3), ("us", 1e-6), ("min", 60.0)),
    "m^3/s": (("l/min", 1e-3 / 60.0), ("l/s", 1e-3), ("cm^3/s", 1e-6), ("m^3/h", 1 / 3600.0)),
    "Pa": (("bar", 1e5), ("kPa", 1e3), ("MPa", 1e6), ("mbar", 100.0), ("psi", 6894.757)),
    "N": (("kN", 1e3), ("daN", 10.0), ("mN", 1e-3)),
    "m/s": (("mm/s", 1e-3), ("km/h", 1 / 3.6)),
    "m/s^2": (("g", 9.80665), ("mm/s^2", 1e-3)),
    "A": (("mA", 1e-3),),
}
SI = {"displacement": "m", "force": "N", "dp": "Pa", "flow": "m^3/s", "rod acceleration": "m/s^2",
      "velocity": "m/s", "current": "A", "time": "s"}


@dataclass(frozen=True)
class ProtocolSpec:
    """What a record of one test must look like (from conf/test/<test>.yaml)."""

    test: str
    protocol: str
    path: str
    rates: dict           # run label -> sampling rate [Hz]
    targets: dict         # run label -> {quantity: peak |value| of the excitation (SI)}
    configurations: dict  # run label -> configuration ("valve", "damper", "module", "topmount")
    valves: tuple         # flow bench: the valves the protocol names


def default_conf() -> Path:
    """The project's conf/ (around the working directory, else the package's repository)."""
    from ..config import repo_root

    try:
        return repo_root(Path.cwd()) / "conf"
    except FileNotFoundError:
        return repo_root(Path(__file__).parent) / "conf"


def protocol_spec(test: str, conf: str | Path | None = None) -> ProtocolSpec:
    """The checks' view of ``conf/test/<test>.yaml`` (ProtocolError naming the file if it is bad)."""
    path = Path(conf if conf is not None else default_conf()) / "test" / f"{test}.yaml"
    if not path.is_file():
        raise DataError([f"{path}: no protocol for test {test!r} (expected conf/test/<test>.yaml)"])
    return _spec(str(path.resolve()), path.stat().st_mtime_ns, test)


@lru_cache(maxsize=32)
def _spec(path: str, mtime: int, test: str) -> ProtocolSpec:
    from ..protocols import build_runs, load_protocol

    doc = load_protocol(path)
    rates, targets, confs = {}, {}, {}
    for r in build_runs(doc, 0):
        rates[r.name] = float(r.rate)
        q = {"valve": "flow", "active_valve": "dp"}.get(r.configuration, "displacement")
        targets[r.name] = {q: float(np.max(np.abs(r.excitation.value)))}
        confs[r.name] = r.configuration
    return ProtocolSpec(test, doc["protocol"], path, rates, targets, confs, tuple(doc.get("valves", {}) or ()))


def read_record(path: str | Path, test: str | None = None, *, conf: str | Path | None = None,
                valve: str | None = None, current_range: tuple[float, float] | None = None,
                require: tuple[str, ...] = ()) -> tuple[pd.DataFrame, dict]:
    """Read and check a measurement file (see the module docstring). ``test``:
    the standard test it records (conf/test/<test>.yaml; None: the protocol
    its metadata names, else the generic checks); ``valve``: the valve a
    flow-bench record must hold; ``require``: quantities a generic record needs.
    Returns (frame, metadata); raises DataError naming file, run and column."""
    df, meta = read_table(path)
    return check_record(df, meta, str(path), test, conf=conf, valve=valve, current_range=current_range,
                        require=require), meta


def check_record(df: pd.DataFrame, meta: dict, where: str, test: str | None = None, *,
                 conf: str | Path | None = None, valve: str | None = None,
                 current_range: tuple[float, float] | None = None, require: tuple[str, ...] = ()) -> pd.DataFrame:
    """:func:`read_record` on a frame in memory (``where`` names it)."""
    mp = meta.get("protocol")
    if test is None and isinstance(mp, str) and mp.isidentifier():  # lab and imported files name their test
        if (Path(conf if conf is not None else default_conf()) / "test" / f"{mp}.yaml").is_file():
            test = mp
    if test is None:
        return _check_generic(df, meta, where, current_range, require)
    spec = protocol_spec(test, conf)
    errors = _label_errors(df, meta, where, spec, valve)
    if "module" in spec.configurations.values() and "rod acceleration [m/s^2]" not in df:
        errors.append(f"{where}: missing column 'rod acceleration [m/s^2]' (a module test, {spec.path})")
    rates = set(spec.rates.values())
    if spec.protocol in MIN_RATE:  # any measured rate >= MIN_RATE (checked by check_frame), not the protocol's
        rates = {None}
    try:
        df = check_frame(df, meta, where, spec.protocol, current_range=current_range,
                         rate=rates.pop() if len(rates) == 1 else spec.rates)
    except DataError as e:
        raise DataError(errors + e.errors) from None
    if errors:
        raise DataError(errors)
    for name, g in _groups(df):
        label = f"{where} run {name!r}" if name is not None else where
        tg = spec.targets.get(name)
        if tg is None:  # a label the protocol lacks was refused above unless there is no run column
            tg = {q: max(t[q] for t in spec.targets.values() if q in t)
                  for q in ("displacement", "flow") if any(q in t for t in spec.targets.values())}
        cfg = spec.configurations.get(name) or next(iter(spec.configurations.values()))
        errors += _magnitude_errors(g, label, tg, spec.path)
        errors += _current_errors(g, label, name)
        if not errors:
            errors += _velocity_errors(g, label)
        if not errors:
            errors += _sign_errors(g, label, cfg)
    if errors:
        raise DataError(errors)
    return df


def _groups(df):
    if "run" not in df:
        return [(None, df)]
    return [(str(k), g) for k, g in df.groupby("run", sort=False)]


def _label_errors(df, meta, where, spec: ProtocolSpec, valve) -> list[str]:
    """Run labels against the protocol, the file's metadata, its name and the valve asked for."""
    errors = []
    mp = meta.get("protocol")
    if isinstance(mp, str) and mp not in (spec.protocol, spec.test):
        errors.append(f"{where}: metadata says protocol {mp!r}, read as a {spec.protocol!r} record "
                      f"({spec.path}); a record of another test?")
    names = list(spec.rates)
    example = ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")
    if "run" not in df:
        article = "an" if spec.test[0] in "aeiou" else "a"
        errors.append(f"{where}: no 'run' column; {article} {spec.test} record labels each row with its run "
                      f"({example}; {spec.path})")
        return errors
    labels = [str(x) for x in dict.fromkeys(df["run"].tolist()) if isinstance(x, (str, int, np.integer))]
    unknown = [x for x in labels if x not in spec.rates]
    if unknown:
        errors.append(f"{where}: run {unknown[0]!r}" + (f" (and {len(unknown) - 1} more)" if len(unknown) > 1 else "")
                      + f" is not a run of {spec.path} (expected {example}); a record of another test?")
    if spec.protocol == "flowbench":
        from ..variants import VALVE_DESIGNS

        stem = Path(where).stem
        if stem in VALVE_DESIGNS and any(x != VALVE_DESIGNS[stem][0] for x in labels):
            errors.append(f"{where}: the file is named after valve design {stem} ({VALVE_DESIGNS[stem][0]}) but "
                          f"its run column says {', '.join(labels)}")
        if valve is not None and any(x != valve for x in labels):
            errors.append(f"{where}: run column says {', '.join(labels)}; expected a record of valve {valve!r}")
    return errors


def mixup(ratio: float, si: str) -> str:
    """The unit a value ``ratio`` times its expected size was likely written in."""
    if not ratio > 0:
        return "wrong unit or scale?"
    best = min(MIXUPS.get(si, ()), key=lambda uf: abs(math.log10(ratio * uf[1])), default=None)
    if best is None or abs(math.log10(ratio * best[1])) > math.log10(PLAUSIBLE_FACTOR):
        return "wrong unit or scale?"
    return f"values in {best[0]} under a [{si}] header?"


def _magnitude_errors(g: pd.DataFrame, label: str, targets: dict, path: str) -> list[str]:
    errors = []
    for q, si in SI.items():
        col = f"{q} [{si}]"
        if q == "time" or col not in g:
            continue
        peak = float(np.max(np.abs(g[col].to_numpy(float))))
        if q in targets and targets[q] > 0 and peak > 0:
            r = peak / targets[q]
            if not 1.0 / PLAUSIBLE_FACTOR <= r <= PLAUSIBLE_FACTOR:
                errors.append(f"{label}: column {col!r}: peak {peak:.4g} {si} is {r:.3g}x the protocol's "
                              f"{targets[q]:.4g} {si} ({path}): {mixup(r, si)}")
                continue
        lo, hi = PEAK_RANGE.get(q, (None, None))
        if hi is not None and peak > hi:
            errors.append(f"{label}: column {col!r}: peak {peak:.4g} {si} above the physical {hi:g} {si} of a damper "
                          f"test: {mixup(peak / TYPICAL[q], si)}")
        elif lo is not None and 0 < peak < lo:
            errors.append(f"{label}: column {col!r}: peak {peak:.4g} {si} below the {lo:g} {si} of a damper test: "
                          f"{mixup(peak / TYPICAL[q], si)}")
    return errors


def _sign_errors(g: pd.DataFrame, label: str, configuration: str) -> list[str]:
    """A passive part dissipates: int F dx > 0 (damper, friction), F in phase with x
    (top mount), int dp q dt > 0 (valve). A clear opposite sign is a flipped channel."""
    if configuration in ("valve", "active_valve"):
        if "dp [Pa]" not in g or "flow [m^3/s]" not in g:
            return []
        p, q = g["dp [Pa]"].to_numpy(float), g["flow [m^3/s]"].to_numpy(float)
        w, scale = float(np.sum(p * q)), float(np.sum(np.abs(p * q)))
        if scale > 0 and w < -SIGN_TOL * scale:
            return [f"{label}: columns 'dp [Pa]' and 'flow [m^3/s]': the valve generates hydraulic power "
                    f"(dp against the flow); dp or flow sign flipped? expected dp > 0 in the direction of flow"]
        return []
    if "force [N]" not in g:
        return []
    F = g["force [N]"].to_numpy(float)
    if "displacement [m]" in g:
        x = g["displacement [m]"].to_numpy(float)
        dx = np.diff(x)
    elif "velocity [m/s]" in g:
        t = g["time [s]"].to_numpy(float)
        v = g["velocity [m/s]"].to_numpy(float)
        dx = 0.5 * (v[1:] + v[:-1]) * np.diff(t)
        x = None
    else:
        return []
    if configuration == "topmount" and x is not None:
        xc, Fc = x - x.mean(), F - F.mean()
        den = float(np.sqrt(np.sum(xc**2) * np.sum(Fc**2)))
        if den > 0 and float(np.sum(xc * Fc)) / den < -0.3:
            return [f"{label}: column 'force [N]' falls as the displacement rises (a negative stiffness): force "
                    f"sign flipped? expected the mount's force in the direction of its deflection"]
        return []
    Fm = 0.5 * (F[1:] + F[:-1])
    w, scale = float(np.sum(Fm * dx)), float(np.sum(np.abs(Fm * dx)))
    if scale > 0 and w < -SIGN_TOL * scale:
        return [f"{label}: column 'force [N]': the record generates energy (int F dx = {w:.3g} J < 0) where a "
                f"damper dissipates: force sign flipped? expected the force positive with positive velocity "
                f"(rebound); an importer mapping can say scale: -1"]
    return []


CURRENT_TOL = 0.05  # [A] a record's mean current against the one its run label names (I1.6: 1.6 A)


def _current_errors(g: pd.DataFrame, label: str, run) -> list[str]:
    """The active valve's current is >= 0 and, where the run label names it
    (``..._I1.6``), within CURRENT_TOL of it (a column of zeros: a passive
    damper, whose runs keep the protocol's labels)."""
    if "current [A]" not in g:
        return []
    i = g["current [A]"].to_numpy(float)
    if np.min(i) < 0:
        return [f"{label}: column 'current [A]' is negative ({np.min(i):.4g} A); expected the valve's current >= 0 "
                f"(a sign or scale in the mapping?)"]
    m = re.search(r"(?:^|_)I(\d+(?:\.\d+)?)$", str(run)) if run is not None else None
    if not np.any(i):  # a passive damper (no active valve): the run labels keep the protocol's currents
        return []
    if m and float(m.group(1)) > 0 and abs(float(np.mean(i)) - float(m.group(1))) > CURRENT_TOL:
        return [f"{label}: column 'current [A]' averages {np.mean(i):.4g} A where the run label names "
                f"{m.group(1)} A: {mixup(float(np.mean(i)) / float(m.group(1)), 'A')}"]
    return []


def _velocity_errors(g: pd.DataFrame, label: str) -> list[str]:
    """A velocity column beside a displacement column must be its rate: the
    integrated velocity (a constant offset and a linear drift removed from
    both) against the displacement, correlation >= VELOCITY_MIN_CORR and a
    gain within VELOCITY_MAX_GAIN of 1 (integration, not differentiation:
    the displacement's quantisation noise stays small)."""
    if "velocity [m/s]" not in g or "displacement [m]" not in g:
        return []
    t = g["time [s]"].to_numpy(float)
    v, x = g["velocity [m/s]"].to_numpy(float), g["displacement [m]"].to_numpy(float)
    xv = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    A = np.column_stack([np.ones_like(t), t - t[0]])
    xv = xv - A @ np.linalg.lstsq(A, xv, rcond=None)[0]
    xd = x - A @ np.linalg.lstsq(A, x, rcond=None)[0]
    den = float(np.sqrt(np.sum(xv * xv) * np.sum(xd * xd)))
    if den == 0.0:
        return []  # a constant channel is named by the dead-channel check
    corr, gain = float(np.sum(xv * xd)) / den, float(np.sum(xv * xd) / np.sum(xv * xv))
    if corr <= -VELOCITY_MIN_CORR:
        return [f"{label}: column 'velocity [m/s]' runs against the displacement's rate (correlation {corr:.2f}): "
                f"velocity sign flipped? expected velocity = d(displacement)/dt"]
    if corr < VELOCITY_MIN_CORR:
        return [f"{label}: column 'velocity [m/s]' is not the displacement's rate (correlation {corr:.2f} of the "
                f"integrated velocity with the displacement; expected >= {VELOCITY_MIN_CORR})"]
    if not 1.0 / VELOCITY_MAX_GAIN <= gain <= VELOCITY_MAX_GAIN:
        return [f"{label}: column 'velocity [m/s]' is {1 / gain:.3g}x the displacement's rate: "
                f"{mixup(1 / gain, 'm/s')}"]
    return []


def _check_generic(df, meta, where, current_range, require) -> pd.DataFrame:
    df = check_frame(df, meta, where, None, current_range=current_range)
    errors = []
    cols = {str(c).split("[")[0].strip(): c for c in df.columns if c != "run"}
    for q in require:
        alts = q.split("|")
        if not any(a in cols for a in alts):
            errors.append(f"{where}: missing column " + " or ".join(repr(f"{a} [{SI[a]}]") for a in alts))
    for name, g in _groups(df):
        label = f"{where} run {name!r}" if name is not None else where
        t = g["time [s]"].to_numpy(float)
        if len(t) >= 2:
            fs = (len(t) - 1) / (t[-1] - t[0])
            lo, hi = GENERIC_RATE
            if not lo <= fs <= hi:
                errors.append(f"{label}: column 'time [s]': sampling rate {fs:.4g} Hz outside the {lo:g} .. {hi:g} Hz "
                              f"of a bench record: " + ("time in ms (or us) under a [s] header?" if fs < lo
                                                        else "time in s under a smaller unit's header?"))
        if len(t) < GENERIC_MIN[0] or (len(t) >= 2 and t[-1] - t[0] < GENERIC_MIN[1]):
            errors.append(f"{label}: {len(t)} samples over {t[-1] - t[0] if len(t) >= 2 else 0.0:.3g} s; a bench "
                          f"record needs at least {GENERIC_MIN[0]} samples over {GENERIC_MIN[1]:g} s")
            continue
        for q in ("displacement", "force", "velocity", "rod acceleration", "dp", "flow"):
            c = f"{q} [{SI[q]}]"
            if c in g and np.ptp(g[c].to_numpy(float)) == 0:
                errors.append(f"{label}: column {c!r} is constant ({float(g[c].iloc[0])!r}); expected a record of an "
                              f"excited test (sensor disconnected?)")
        if not errors:
            errors += _magnitude_errors(g, label, {}, "")
        if not errors:
            errors += _velocity_errors(g, label)
        if not errors:
            errors += _sign_errors(g, label, "damper")
    if errors:
        raise DataError(errors)
    return df


__all__ = ["read_record", "check_record", "protocol_spec", "ProtocolSpec", "mixup", "PLAUSIBLE_FACTOR",
           "PEAK_RANGE", "GENERIC_RATE"]
